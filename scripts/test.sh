#!/usr/bin/env bash
# The whole test suite: set up (the venv, and chromium for the browser tests), then run pytest.
# Arguments are passed to pytest. Screenshots of the browser tests land in test-artifacts/browser/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/setup-browser.sh
exec .venv/bin/python -m pytest -q "$@"
