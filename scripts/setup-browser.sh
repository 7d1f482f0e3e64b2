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
if ! command -v apt-get >/dev/null 2>&1; then
    echo "the browser tests need chromium at /usr/bin/chromium (or SUNBENCH_CHROMIUM=/path/to/chromium);" \
         "this is not a Debian/Ubuntu machine, so install it by hand" >&2
    exit 1
fi
sudo=""
if [ "$(id -u)" -ne 0 ]; then
    # -n: never wait for a password nobody will type (CI); say what to do instead
    if ! command -v sudo >/dev/null 2>&1 || ! sudo -n true 2>/dev/null; then
        echo "installing chromium needs root: run 'apt-get install chromium' as root, then try again" >&2
        exit 1
    fi
    sudo="sudo -n"
fi
echo "installing Debian's chromium for the browser tests (once)" >&2
export DEBIAN_FRONTEND=noninteractive
# the package lists of a fresh machine may be stale or missing: update only when the first try fails
if ! $sudo apt-get install -y -qq --no-install-recommends chromium >/dev/null; then
    $sudo apt-get update -qq
    $sudo apt-get install -y -qq --no-install-recommends chromium >/dev/null
fi
if [ ! -x "$chromium" ]; then  # e.g. Ubuntu, whose chromium package installs a snap elsewhere
    echo "chromium was installed but is not at $chromium: set SUNBENCH_CHROMIUM=/path/to/chromium" >&2
    exit 1
fi
