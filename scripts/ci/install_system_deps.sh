#!/usr/bin/env bash
# Installs the system libraries the project needs where they are missing (Debian/Ubuntu):
# Python's venv module and Mesa's EGL for headless rendering; with --test, Debian's Chromium too
# (the tests open the pages in it). Does nothing when all are present.
set -euo pipefail
missing=()
[ "${1:-}" = "--test" ] && ! command -v chromium >/dev/null && missing+=(chromium)
python3 -c "import ensurepip, venv" 2>/dev/null || missing+=(python3-venv)
ldconfig -p | grep -q 'libEGL.so.1' || missing+=(libegl1)
ldconfig -p | grep -q 'libEGL_mesa.so.0' || missing+=(libegl-mesa0 libgl1-mesa-dri)
ldconfig -p | grep -q 'libGL.so.1' || missing+=(libgl1)
[ ${#missing[@]} -eq 0 ] && exit 0
echo "installing system packages: ${missing[*]}"
sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}"
