#!/usr/bin/env bash
# The main job: set up, then run the demo (simulate a seed 003 calibration run and fit it).
# Arguments are passed to `sunbench demo` (try --help).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/sunbench demo "$@"
