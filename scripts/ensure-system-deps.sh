#!/usr/bin/env bash
# VTK renders through the system's OpenGL/EGL libraries (Mesa, in software when
# there is no GPU), and the Qt window needs X's xcb libraries. A fresh Debian may
# lack them: install them when we are root, otherwise say what is missing.
set -u
missing=()
for lib in libEGL.so.1 libGL.so.1 libX11.so.6 libXrender.so.1 libxkbcommon-x11.so.0 libxcb-cursor.so.0 \
           libxcb-icccm.so.4 libxcb-keysyms.so.1 libxcb-shape.so.0 libfontconfig.so.1 libdbus-1.so.3; do
  ldconfig -p 2>/dev/null | grep -q "$lib" || missing+=("$lib")
done
[ ${#missing[@]} -eq 0 ] && exit 0
packages="libegl1 libgl1 libgl1-mesa-dri libglx-mesa0 libegl-mesa0 libx11-6 libxrender1 libxext6 \
libxkbcommon0 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-image0 libxcb-keysyms1 libxcb-randr0 \
libxcb-render-util0 libxcb-shape0 libxcb-xinerama0 libxcb-xkb1 libxcb-xfixes0 libfontconfig1 libdbus-1-3 \
fonts-dejavu-core"
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  echo "installing the OpenGL and X libraries VTK and Qt need (${missing[*]} missing): $packages"
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $packages >/dev/null
else
  echo "warning: ${missing[*]} not found; the window needs them. Install: sudo apt-get install $packages"
fi
exit 0
