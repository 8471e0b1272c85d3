#!/usr/bin/env bash
# riverbench quick start. Each command installs what is missing, then runs:
#   ./dev.sh demo    run the quickstart scenario (riverbench run quickstart) and write runs/quickstart-<time>/
#   ./dev.sh test    run the test suite (extra args go to pytest)
# Works as root on a fresh Debian 12 (Python 3.11); elsewhere install the system packages by hand.
set -euo pipefail
cd "$(dirname "$0")"

SYSTEM_PACKAGES=(python3 python3-venv libusb-1.0-0 libgomp1 libgl1 libegl1 libx11-6)
VENV=.venv
PY="$VENV/bin/python"

install_system() {
    command -v dpkg-query >/dev/null || return 0
    local missing=()
    for pkg in "${SYSTEM_PACKAGES[@]}"; do
        dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "ok installed" || missing+=("$pkg")
    done
    ((${#missing[@]} == 0)) && return 0
    echo "installing system packages: ${missing[*]}"
    local sudo=""
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

install_python() {
    local stamp="$VENV/.installed-$(cat pyproject.toml constraints.txt | sha256sum | cut -c1-16)"
    [ -f "$stamp" ] && return 0
    [ -x "$PY" ] || python3 -m venv "$VENV"
    "$PY" -m pip install -q --upgrade pip
    "$PY" -m pip install -q -c constraints.txt -e ".[test,dev]"
    rm -f "$VENV"/.installed-*
    touch "$stamp"
}

install_system
install_python

case "${1:-}" in
    demo) shift; exec "$VENV/bin/riverbench" run quickstart "$@" ;;
    # at most 8 tests queued per worker: the one running the long library suite is not left a backlog the other cannot take
    test) shift; exec "$PY" -m pytest -n 2 --maxschedchunk 8 "$@" ;;
    *) echo "usage: ./dev.sh demo | test [args]" >&2; exit 2 ;;
esac
