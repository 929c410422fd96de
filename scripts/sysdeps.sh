#!/usr/bin/env bash
# Find the system libraries open3d's shared objects need and that the loader cannot find
# (ldd "not found"), map each to its Debian package, and install them when we are root;
# otherwise print the exact apt-get command and fail. Called by the Makefile after pip.
set -euo pipefail
venv=${1:-.venv}
site=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
o3d="$site/open3d"
if [ ! -d "$o3d" ]; then
  echo "sysdeps: open3d is not installed in $venv" >&2
  exit 1
fi
# Only the core library and its Python binding: the optional torch/tensorflow op libraries
# link libraries we never load.
missing=$(find "$o3d" -maxdepth 2 \( -name 'pybind*.so' -o -name 'libOpen3D.so*' \) -print0 \
  | xargs -0 -n1 ldd 2>/dev/null | awk '/not found/ {print $1}' | sort -u)
[ -z "$missing" ] && exit 0

declare -A pkg_of=(
  [libusb-1.0.so.0]=libusb-1.0-0 [libudev.so.1]=libudev1 [libEGL.so.1]=libegl1
  [libGL.so.1]=libgl1 [libGLX.so.0]=libglx0 [libOpenGL.so.0]=libopengl0
  [libX11.so.6]=libx11-6 [libxcb.so.1]=libxcb1 [libXext.so.6]=libxext6
  [libidn2.so.0]=libidn2-0 [libgomp.so.1]=libgomp1 [libstdc++.so.6]=libstdc++6
  [libtbb.so.12]=libtbb12
)
pkgs=()
for lib in $missing; do
  p=${pkg_of[$lib]:-}
  if [ -z "$p" ]; then
    echo "sysdeps: open3d needs $lib, which is missing; find its package with: apt-file search $lib" >&2
    exit 1
  fi
  pkgs+=("$p")
done
pkgs=($(printf '%s\n' "${pkgs[@]}" | sort -u))
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  echo "sysdeps: installing ${pkgs[*]} for open3d (missing: $(echo $missing))"
  DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${pkgs[@]}" >/dev/null
else
  echo "sysdeps: open3d needs system libraries that are missing: $(echo $missing)" >&2
  echo "sysdeps: run as root: apt-get update && apt-get install -y ${pkgs[*]}" >&2
  exit 1
fi
