#!/usr/bin/env bash
# Other people's client software that the peer tests (tests/peers/) drive the simulators with, each in a
# virtual environment of its own under .venv-peers/NAME (their dependency pins must not touch sunbench's),
# and INDI's LX200 drivers from Debian's indi-bin, installed with apt-get like chromium. Safe to run again:
# a venv is rebuilt only when its package list below changes. A peer that cannot be installed makes its
# tests fail with the command that installs it; nothing is skipped.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
mkdir -p .venv-peers
# one installer at a time: two runs at once would rebuild the same venv under each other
exec 9>.venv-peers/.lock
flock 9

# peer_venv NAME PACKAGE==VERSION ...: the client in .venv-peers/NAME, pinned to the version that was tried
peer_venv() {
    local name=$1
    shift
    local dir=.venv-peers/$name want
    want=$(printf '%s\n' "$@" | sha256sum | cut -d' ' -f1)
    if [ -x "$dir/bin/python" ] && [ "$(cat "$dir/.installed" 2>/dev/null)" = "$want" ]; then
        return 0
    fi
    echo "installing the peer client '$name' ($*) into $dir" >&2
    rm -rf "$dir"
    "$PYTHON" -m venv "$dir"
    "$dir/bin/python" -m pip install --quiet --upgrade pip
    # "--no-deps PKG" after the list: PKG itself without its declared dependencies (given in the list instead)
    local args=() nodeps=()
    while [ $# -gt 0 ]; do
        if [ "$1" = "--no-deps" ]; then nodeps+=("$2"); shift 2; else args+=("$1"); shift; fi
    done
    if "$dir/bin/python" -m pip install --quiet "${args[@]}" && \
        { [ ${#nodeps[@]} -eq 0 ] || "$dir/bin/python" -m pip install --quiet --no-deps "${nodeps[@]}"; }; then
        echo "$want" > "$dir/.installed"
    else
        echo "WARNING: could not install the peer client '$name'; its tests will fail saying so" >&2
    fi
}

peer_venv qmi "qmi==0.54.2"
peer_venv pylablib "pylablib==1.4.5" "pyserial>=3.5"
peer_venv pystages "pystages==1.4.2"
peer_venv pyvisa "pyvisa==1.16.2" "pyvisa-py==0.8.1" "pymeasure==0.16.0"
peer_venv lantz "lantz-core==0.5.3" "lantz-drivers==0.5.2" "pyvisa" "pyvisa-py==0.8.1" "pyserial>=3.5"
# instrumentkit 0.6.0 pins ruamel.yaml ~=0.15 (no wheel for Python >= 3.10) and enum34 (which shadows the
# standard enum on Python 3): its other dependencies are installed, then the package itself without them
peer_venv instrumentkit numpy "pyserial>=3.3" "pyvisa>=1.9" "quantities>=0.12.1" "future>=0.15" \
    "python-vxi11>=0.8" python-usbtmc pyusb "ruamel.yaml<0.18" --no-deps "instrumentkit==0.6.0"

# INDI (Debian's indi-bin): indiserver and the LX200 drivers
if ! command -v indiserver >/dev/null 2>&1; then
    bash scripts/apt-install.sh indi-bin "the INDI peer tests" || \
        echo "WARNING: no indi-bin; the INDI peer tests will fail saying so" >&2
fi
