#!/usr/bin/env bash
# Instruction counts of the demo frame, for A/B comparisons this VM's
# clock cannot settle (its frame times spread ±15 % run to run; counts
# do not move). Runs `quadtex demo` under valgrind's callgrind three times:
# the texture build alone (an 8-pixel-wide frame), the `nearest` frame and
# the `quadtree` frame at WIDTH, and prints each frame's instructions less
# the build's and less writing the PNG (`Output::save_image`, inclusive:
# the same for both filters, so leaving it in would flatter the ratio), the
# ratio and the filter's share (quadtree − nearest) / nearest.
#
# Usage: bench/instructions.sh [QUADTEX_BINARY] [WIDTH]
# (default: target/release/quadtex, 960; needs valgrind: apt-get install
# valgrind). Instructions are not time: cache misses and divisions cost
# more than their count, so a change is confirmed on the clock too.
set -euo pipefail
bin="${1:-target/release/quadtex}"
width="${2:-960}"
command -v valgrind >/dev/null || { echo "valgrind not found (apt-get install valgrind)" >&2; exit 1; }
[ -x "$bin" ] || { echo "$bin: not an executable (cargo build --release first)" >&2; exit 1; }
dir="$(mktemp -d)"
trap 'rm -rf "$dir"' EXIT
# Instructions of one run, less those of writing its image.
count() {
  local out="$dir/out.$1.$2" total save
  total=$(valgrind --tool=callgrind --callgrind-out-file="$out" "$bin" demo \
    --width "$2" --filter "$1" -o "$dir/frame.png" 2>&1 \
    | sed -n 's/.*I *refs: *\([0-9,]*\).*/\1/p' | tr -d ,)
  save=$(callgrind_annotate --inclusive=yes --threshold=100 --auto=no "$out" 2>/dev/null \
    | awk '/Output::save_image/ { gsub(",", "", $1); print $1; exit }')
  [ -n "$save" ] || { echo "no Output::save_image in the profile of $1 at $2" >&2; exit 1; }
  echo $(( total - save ))
}
build=$(count nearest 8)
nearest=$(( $(count nearest "$width") - build ))
quadtree=$(( $(count quadtree "$width") - build ))
awk -v b="$build" -v n="$nearest" -v q="$quadtree" -v w="$width" 'BEGIN {
  printf "demo at width %d, instructions (callgrind)\n", w
  printf "  texture build       %8.3f G\n", b / 1e9
  printf "  nearest frame       %8.3f G\n", n / 1e9
  printf "  quadtree frame      %8.3f G\n", q / 1e9
  printf "  quadtree / nearest  %8.2f\n", q / n
  printf "  filter share        %8.2f  ((quadtree - nearest) / nearest)\n", (q - n) / n
}'
