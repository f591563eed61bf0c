#!/usr/bin/env bash
# Installs Intel Embree's development files (Debian: libembree-dev, Embree
# 3.13) and a C++ compiler unless present.
set -euo pipefail
if [ -f /usr/include/embree3/rtcore.h ] && command -v g++ >/dev/null; then
  exit 0
fi
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
$sudo apt-get update
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y libembree-dev g++ pkg-config
