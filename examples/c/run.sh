#!/usr/bin/env bash
# Builds the C API's static library (cargo's debug profile; or takes the one
# QUADTEX_CAPI_LIB names, as scripts/test does with the one `cargo test`
# built), compiles
# examples/c/filter.c against include/quadtex.h with strict warnings, and runs
# it from the repository root (it packs samples/threshold.svg and checks the
# colours it filters). Extra arguments are passed to the program.
set -euo pipefail
cd "$(dirname "$0")/../.."

cc="${CC:-cc}"
if ! command -v "$cc" >/dev/null 2>&1; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y gcc
  cc=gcc
fi

target="${CARGO_TARGET_DIR:-target}"
lib="${QUADTEX_CAPI_LIB:-}"
if [ -z "$lib" ]; then
  cargo build -p quadtex-capi
  lib="$target/debug/libquadtex_capi.a"
fi
out="$target/c-examples"
mkdir -p "$out"
# Link the archive by name (not -lquadtex_capi, which would pick the .so).
# What the Rust standard library needs on Linux (`--print native-static-libs`;
# -lrt and -lutil matter on glibc before 2.34, gcc adds -lgcc_s and -lc).
"$cc" -std=c11 -Wall -Wextra -Werror -pedantic -Iinclude \
  examples/c/filter.c "$lib" -lpthread -ldl -lm -lrt -lutil -o "$out/filter"
"$out/filter" "$@"
