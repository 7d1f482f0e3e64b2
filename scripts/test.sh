#!/usr/bin/env bash
# The whole test suite: set up (the venv, a C compiler, chromium for the browser tests, the peer clients), then run
# pytest.
# Arguments are passed to pytest. Screenshots of the browser tests land in test-artifacts/browser/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# a C compiler for the tests that compile the exported C headers (Debian's gcc); without one they fail, saying so
command -v cc >/dev/null 2>&1 || command -v gcc >/dev/null 2>&1 \
    || bash scripts/apt-install.sh gcc "the C-header tests" || echo "WARNING: no C compiler (see above)" >&2
# without chromium the rest of the suite still runs; the browser tests then fail, saying how to get it
bash scripts/setup-browser.sh || echo "WARNING: no chromium for the browser tests (see above)" >&2
# other people's clients for the peer tests (tests/peers/): their own venvs in .venv-peers/, INDI from Debian
bash scripts/setup-peers.sh || echo "WARNING: some peer clients are missing (see above)" >&2
exec .venv/bin/python -m pytest -q "$@"
