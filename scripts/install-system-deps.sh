#!/usr/bin/env bash
# Install the Debian 12 system packages that the Qt 6 (PySide6-Essentials
# wheels) xcb platform plugin and VTK (pyvista wheels) need to run under Xvfb.
# Only installs what is missing (checked with dpkg-query); `apt-get update`
# runs only when something has to be installed.
#
# Usage: scripts/install-system-deps.sh [--check]
#   --check   only report missing packages; exit 1 if any are missing.
set -euo pipefail

PACKAGES=(
    # virtual X server for the GUI tests and `make run` on a headless box
    xvfb
    xauth
    # OpenGL / EGL (VTK renders through GLX with Mesa's llvmpipe under Xvfb)
    libgl1
    libegl1
    libgl1-mesa-dri
    libglx-mesa0
    # Qt xcb platform plugin
    libxkbcommon0
    libxkbcommon-x11-0
    libxcb1
    libxcb-cursor0
    libxcb-icccm4
    libxcb-image0
    libxcb-keysyms1
    libxcb-randr0
    libxcb-render0
    libxcb-render-util0
    libxcb-shape0
    libxcb-shm0
    libxcb-sync1
    libxcb-xinerama0
    libxcb-xfixes0
    libxcb-xkb1
    libx11-xcb1
    libdbus-1-3
    libfontconfig1
    libfreetype6
    libglib2.0-0
    # X libraries used by VTK's X render window
    libx11-6
    libxrender1
    libxi6
    libsm6
    libice6
    libxext6
    libxt6
    libxcursor1
    # fonts, so Qt and VTK text is readable
    fonts-dejavu-core
)

missing=()
for pkg in "${PACKAGES[@]}"; do
    status=$(dpkg-query -W -f='${db:Status-Abbrev}' "$pkg" 2>/dev/null || true)
    if [[ "$status" != ii* ]]; then
        missing+=("$pkg")
    fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
    echo "install-system-deps: all ${#PACKAGES[@]} system packages present"
    exit 0
fi

echo "install-system-deps: missing system packages: ${missing[*]}"
if [[ "${1:-}" == "--check" ]]; then
    exit 1
fi

fail_no_root() {
    echo "install-system-deps: ERROR: root (or sudo) is needed to install these Debian packages:" >&2
    echo "    ${missing[*]}" >&2
    echo "Install them with:  sudo apt-get install -y ${missing[*]}" >&2
    exit 1
}

if [[ $(id -u) -eq 0 ]]; then
    SUDO=()
elif command -v sudo >/dev/null 2>&1; then
    # -n: never prompt when there is no terminal (CI); prompt otherwise.
    if [[ -t 0 ]]; then SUDO=(sudo); else SUDO=(sudo -n); fi
    "${SUDO[@]}" true 2>/dev/null || fail_no_root
else
    fail_no_root
fi

"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "install-system-deps: installed ${missing[*]}"
