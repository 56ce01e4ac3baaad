#!/usr/bin/env bash
# Installs the Debian packages lancer needs, only those missing, non-interactively.
# A second run finds everything present and returns in well under a second.
set -euo pipefail

packages=(
  cmake ninja-build g++ make pkg-config
  libassimp-dev libtbb-dev libpng-dev libcli11-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libembree-dev libopenexr-dev
  libopenmpi-dev openmpi-bin
  clang-format
  # The sanitized build (make test-sanitize) compiles with clang and links its sanitizer runtimes.
  clang libclang-rt-dev
  # The Python module (docs/python.md) targets Debian's interpreter, /usr/bin/python3, where these live;
  # Open3D is the peer its tests and benchmark compare with.
  python3-dev pybind11-dev python3-numpy python3-pytest python3-setuptools python3-pip python3-open3d
)

missing=()
for package in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$package")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "deps: installing ${missing[*]}" >&2
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  sudo_cmd=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
