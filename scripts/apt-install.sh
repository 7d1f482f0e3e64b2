#!/usr/bin/env bash
# apt-install.sh PACKAGE WHAT: install one Debian package with apt-get (with `sudo -n` when not root, so CI
# never waits for a password), updating the package lists only when the first try fails (a fresh machine's
# may be stale or missing). WHAT says what needs it, for the messages. Exits 1, saying what to do, when the
# package cannot be installed here.
set -euo pipefail
package=$1
what=$2
if ! command -v apt-get >/dev/null 2>&1; then
    echo "$what need(s) Debian's $package; this is not a Debian/Ubuntu machine, so install it by hand" >&2
    exit 1
fi
sudo=""
if [ "$(id -u)" -ne 0 ]; then
    if ! command -v sudo >/dev/null 2>&1 || ! sudo -n true 2>/dev/null; then
        echo "installing $package needs root: run 'apt-get install $package' as root, then try again" >&2
        exit 1
    fi
    sudo="sudo -n"
fi
echo "installing Debian's $package for $what (once)" >&2
export DEBIAN_FRONTEND=noninteractive
if ! $sudo apt-get install -y -qq --no-install-recommends "$package" >/dev/null; then
    $sudo apt-get update -qq
    $sudo apt-get install -y -qq --no-install-recommends "$package" >/dev/null
fi
