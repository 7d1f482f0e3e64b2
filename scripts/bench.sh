#!/usr/bin/env bash
# The benchmarks (tests/perf/bench_*.py): set up, then run each and print its figures.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
for bench in tests/perf/bench_*.py; do
    echo "== $bench"
    .venv/bin/python "$bench"
done
