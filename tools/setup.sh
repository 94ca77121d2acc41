#!/usr/bin/env bash
# One set-up command for a fresh machine: system packages, .venv, usdcrowd and its extras.
#   bash tools/setup.sh            (make setup runs this)
# System packages: libllvm19 for Mitsuba's llvm_ad_rgb variant (Debian 12's LLVM 15
# aborts), Mesa's EGL and DRI drivers for headless OpenGL previews (llvmpipe), and
# Xvfb so the tests can drive the interactive preview window on a virtual screen,
# and the X and GL client libraries Blender's bpy wheel links against (the tests
# import our shots with it, in its own venv).
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES="libllvm19 libegl1 libegl-mesa0 libgl1-mesa-dri libgles2 xvfb"
APT_PACKAGES="$APT_PACKAGES libgl1 libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libxext6 libsm6"
PYTHON="${PYTHON:-python3}"
EXTRAS="${USDCROWD_EXTRAS:-dev,final,preview,edit,distributed,dataset}"

missing=""
if command -v dpkg-query >/dev/null 2>&1; then
    for p in $APT_PACKAGES; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
    done
fi
if [ -n "$missing" ]; then
    if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
        echo "setup: installing system packages:$missing"
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $missing >/dev/null
    else
        echo "setup: these system packages are missing (Mitsuba's LLVM backend, headless OpenGL):$missing"
        echo "setup: run as root:  sudo apt-get install -y$missing"
    fi
fi

if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv with $($PYTHON --version)"
    "$PYTHON" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null
echo "setup: installing usdcrowd[$EXTRAS] into .venv"
.venv/bin/python -m pip install -q -e ".[$EXTRAS]"
.venv/bin/python -c "import usdcrowd, pxr, numpy; print('setup: usdcrowd', usdcrowd.__version__, 'ready in .venv')"
