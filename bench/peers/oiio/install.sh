#!/usr/bin/env bash
# Installs OpenImageIO's development files and tools (Debian) unless present.
set -euo pipefail
if pkg-config --exists OpenImageIO 2>/dev/null && command -v g++ >/dev/null; then
  exit 0
fi
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
$sudo apt-get update
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y libopenimageio-dev openimageio-tools g++ pkg-config
