#!/usr/bin/env bash
# System packages from the distribution, installed when we are root (apt-get), otherwise named
# in the exact apt-get command to run. Called by the Makefile after pip, and before the tests.
#
#   scripts/sysdeps.sh [VENV]            open3d's libraries (required), Mesa's software OpenGL
#                                        (MuJoCo's off-screen rendering) and Chromium (tests)
#   scripts/sysdeps.sh --browser         Chromium only
#
# open3d: find the system libraries its shared objects need and that the loader cannot find
# (ldd "not found"), map each to its Debian package; missing ones fail when we cannot install
# them. Chromium (Debian's chromium and chromium-driver, /usr/bin/chromium) is what the monitor
# page's browser test drives; without it, and not root, we print the command and go on: that
# test is then skipped and says why.
set -euo pipefail
browser_only=0
if [ "${1:-}" = "--browser" ]; then
  browser_only=1
  shift
fi
venv=${1:-.venv}
CHROMIUM=/usr/bin/chromium

is_root() { [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; }

apt_install() {   # what for, then packages
  local what=$1
  shift
  echo "sysdeps: installing $* for $what"
  DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null
}

open3d_packages() {   # prints the packages open3d needs, or fails naming an unknown library
  local site o3d missing lib p
  site=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
  o3d="$site/open3d"
  if [ ! -d "$o3d" ]; then
    echo "sysdeps: open3d is not installed in $venv" >&2
    return 1
  fi
  # Only the core library and its Python binding: the optional torch/tensorflow op libraries
  # link libraries we never load.
  missing=$(find "$o3d" -maxdepth 2 \( -name 'pybind*.so' -o -name 'libOpen3D.so*' \) -print0 \
    | xargs -0 -n1 ldd 2>/dev/null | awk '/not found/ {print $1}' | sort -u)
  [ -z "$missing" ] && return 0
  declare -A pkg_of=(
    [libusb-1.0.so.0]=libusb-1.0-0 [libudev.so.1]=libudev1 [libEGL.so.1]=libegl1
    [libGL.so.1]=libgl1 [libGLX.so.0]=libglx0 [libOpenGL.so.0]=libopengl0
    [libX11.so.6]=libx11-6 [libxcb.so.1]=libxcb1 [libXext.so.6]=libxext6
    [libidn2.so.0]=libidn2-0 [libgomp.so.1]=libgomp1 [libstdc++.so.6]=libstdc++6
    [libtbb.so.12]=libtbb12
  )
  for lib in $missing; do
    p=${pkg_of[$lib]:-}
    if [ -z "$p" ]; then
      echo "sysdeps: open3d needs $lib, which is missing; find its package with: apt-file search $lib" >&2
      return 1
    fi
    echo "$p"
  done | sort -u
}

if [ "$browser_only" = 0 ]; then
  o3d_pkgs=($(open3d_packages))
  if [ "${#o3d_pkgs[@]}" -gt 0 ]; then
    if is_root; then
      apt_install open3d "${o3d_pkgs[@]}"
    else
      echo "sysdeps: open3d needs system libraries that are missing (packages ${o3d_pkgs[*]})" >&2
      echo "sysdeps: run as root: apt-get update && apt-get install -y ${o3d_pkgs[*]}" >&2
      exit 1
    fi
  fi
fi

# MuJoCo (the mujoco extra: the second renderer, hearth/robot/mujoco_render.py) draws off-screen
# through EGL (MUJOCO_GL=egl, the default there) or OSMesa (MUJOCO_GL=osmesa), both software
# rendering by Mesa's llvmpipe on a machine without a GPU. Without them, and not root, we print
# the command and go on: the MuJoCo renderer's tests are then skipped and say why.
if [ "$browser_only" = 0 ]; then
  gl_pkgs=()
  for p in libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || gl_pkgs+=("$p")
  done
  if [ "${#gl_pkgs[@]}" -gt 0 ]; then
    if is_root; then
      apt_install "MuJoCo's off-screen rendering" "${gl_pkgs[@]}"
    else
      echo "sysdeps: MuJoCo's renderer needs Mesa's software OpenGL (packages ${gl_pkgs[*]});" >&2
      echo "sysdeps: run as root: apt-get update && apt-get install -y ${gl_pkgs[*]}" >&2
    fi
  fi
fi

if [ ! -x "$CHROMIUM" ]; then
  if is_root; then
    apt_install "the browser test of the monitor page" chromium chromium-driver
  else
    echo "sysdeps: $CHROMIUM is missing, so the monitor page's browser test will be skipped;" >&2
    echo "sysdeps: run as root: apt-get update && apt-get install -y chromium chromium-driver" >&2
  fi
fi
