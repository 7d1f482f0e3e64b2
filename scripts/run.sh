#!/usr/bin/env bash
# The main job: set up, then serve the dashboard on the simulated bench (http://127.0.0.1:8000/).
# Simulated time runs 10× faster than the wall clock, so the launcher's default campaign (about 17 min on
# a real bench) takes about 2 min. Arguments are passed to `sunbench serve` and win over these defaults
# (e.g. --port 8080, --time-scale 1, --bench my-bench.yaml; try --help). Runs go to the catalogue,
# ~/.local/share/sunbench/catalogue.sqlite unless --catalogue says otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/sunbench serve --time-scale 10 "$@"
