#!/usr/bin/env bash
# The browser the dashboard's tests drive: Debian's chromium, installed once with apt-get. Playwright (a
# Python test dependency, installed by scripts/setup.sh) drives it through executable_path; it never
# downloads a browser of its own (this machine's network reaches the package registries only).
# SUNBENCH_CHROMIUM names another chromium binary and skips the install.
set -euo pipefail

chromium=${SUNBENCH_CHROMIUM:-/usr/bin/chromium}
if [ -x "$chromium" ]; then
    exit 0
fi
if [ -n "${SUNBENCH_CHROMIUM:-}" ]; then
    echo "SUNBENCH_CHROMIUM=$SUNBENCH_CHROMIUM is not an executable file" >&2
    exit 1
fi
bash "$(dirname "$0")/apt-install.sh" chromium "the browser tests"
if [ ! -x "$chromium" ]; then  # e.g. Ubuntu, whose chromium package installs a snap elsewhere
    echo "chromium was installed but is not at $chromium: set SUNBENCH_CHROMIUM=/path/to/chromium" >&2
    exit 1
fi
