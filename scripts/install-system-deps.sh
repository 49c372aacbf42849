#!/usr/bin/env bash
# Install the Debian/Ubuntu packages pito needs: Python's venv, the OpenGL/EGL and
# X/xcb libraries Qt 6 and VTK load at run time, a font with the app's glyphs, and Xvfb for
# headless GUI tests.
# Installs only what is missing; uses sudo when not root.
set -euo pipefail

PKGS=(python3-venv python3-pip
  libgl1 libegl1 libglib2.0-0 libdbus-1-3 libfontconfig1 libfreetype6 libx11-6 libxkbcommon0
  xvfb xauth libx11-xcb1 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-image0
  libxcb-keysyms1 libxcb-randr0 libxcb-render-util0 libxcb-shape0 libxcb-xkb1 libxcb-glx0
  libxcb-util1 libxcb-sync1 libxcb-xfixes0 libxcb-shm0 libxcb-render0 libxcursor1
  fonts-dejavu-core  # DejaVu Sans: the glyphs the app draws (‖ · ± σ); app/fonts.py also loads matplotlib's copy
  iproute2)  # iproute2: `ip link set lo up` in the private network namespace of the LSL tests

if ! command -v dpkg-query >/dev/null 2>&1; then
  echo "install-system-deps: not a Debian/Ubuntu system; install the equivalents of: ${PKGS[*]}" >&2
  exit 0
fi
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install-system-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
