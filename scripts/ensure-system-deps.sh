#!/usr/bin/env bash
# VTK renders through the system's OpenGL/EGL libraries (Mesa, in software when
# there is no GPU). A fresh Debian may lack them: install them when we are root,
# otherwise say what is missing.
set -u
missing=()
for lib in libEGL.so.1 libGL.so.1 libX11.so.6 libXrender.so.1; do
  ldconfig -p 2>/dev/null | grep -q "$lib" || missing+=("$lib")
done
[ ${#missing[@]} -eq 0 ] && exit 0
packages="libegl1 libgl1 libgl1-mesa-dri libglx-mesa0 libegl-mesa0 libx11-6 libxrender1 libxext6"
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  echo "installing the OpenGL libraries VTK needs (${missing[*]} missing): $packages"
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $packages >/dev/null
else
  echo "warning: ${missing[*]} not found; VTK needs them to draw. Install: sudo apt-get install $packages"
fi
exit 0
