#!/usr/bin/env bash
# quadtex's ray caster against Intel Embree 3 on the same rays, in one run:
# builds both sides, dumps the terrain scene's rays once (`quadtex rays`:
# the 1 M-triangle terrain of `quadtex bench --frames`, one primary ray per
# pixel centre and the sun's shadow ray of every lit hit, as the renderer
# casts them), checks Embree's answers against quadtex's, then times each
# side (one thread) in alternating rounds (the order flips every round, so
# drift of the machine hits both sides alike) and prints one Markdown
# table: per side and ray kind the median ns per ray with its min–max over
# the rounds, Mrays/s, and the ratio of quadtex's time to Embree's with its
# spread (min–max of the per-round ratios); then the BVH build times and
# the agreement. Not run by CI.
#
# Usage: bash bench/peers/embree/run.sh [WIDTH] [HEIGHT] [PASSES] [ROUNDS] [QUALITY]
#   PASSES: timing passes per method per round (each side reports its median)
#   ROUNDS: alternating rounds (at least 5)
#   QUALITY: Embree's build quality, high (default) or medium
set -euo pipefail
root=$(cd "$(dirname "$0")/../../.." && pwd)
width=${1:-1920}
height=${2:-1080}
passes=${3:-5}
rounds=${4:-7}
quality=${5:-high}
[ "$rounds" -ge 5 ] || { echo "run.sh: ROUNDS must be at least 5" >&2; exit 2; }
bash "$root/bench/peers/embree/install.sh"
target=${CARGO_TARGET_DIR:-$root/target}
cargo build --release --quiet --manifest-path "$root/Cargo.toml"
qt="$target/release/quadtex"
mkdir -p "$target/peers"
g++ -O2 -std=c++17 -o "$target/peers/embree_rays" "$root/bench/peers/embree/embree_rays.cpp" -lembree3
embree="$target/peers/embree_rays"
out="$target/peers/embree-terrain-${width}x${height}"
mkdir -p "$out"
# The dump (and quadtex's answers), then Embree's check against them (one
# timing pass each: not used).
"$qt" rays terrain -o "$out" --width "$width" --height "$height" --passes 1 >&2
"$embree" "$out" 1 "$quality" >/dev/null 2>"$out/embree-check.txt"
cat "$out/embree-check.txt" >&2
# Alternating rounds: "round<TAB>method<TAB>value" lines for both sides.
times="$out/rounds.tsv"
: >"$times"
for round in $(seq 1 "$rounds"); do
  quadtex_side() {
    "$qt" rays "$out/terrain.toml" -o "$out" --width "$width" --height "$height" --passes "$passes" --timing-only |
      awk -F'\t' -v r="$round" '{ print r "\t" $1 "\t" $2 }' >>"$times"
  }
  embree_side() {
    "$embree" "$out" "$passes" "$quality" 2>/dev/null |
      awk -F'\t' -v r="$round" '{ print r "\t" $1 "\t" $2 }' >>"$times"
  }
  if [ $((round % 2)) -eq 1 ]; then quadtex_side; embree_side; else embree_side; quadtex_side; fi
  echo "round $round of $rounds done" >&2
done
# "median min max" of a column of numbers on stdin (POSIX tools only).
spread() {
  sort -g | awk '{ v[NR] = $1 } END { printf "%s %s %s\n", v[int((NR + 1) / 2)], v[1], v[NR] }'
}
# The spread of method $1's per-round values.
values() {
  awk -F'\t' -v m="$1" '$2 == m { printf "%.6g\n", $3 }' "$times" | spread
}
# The spread of the per-round ratio of method $1's value to method $2's.
ratios() {
  awk -F'\t' -v a="$1" -v b="$2" '
    $2 == a { x[$1] = $3 } $2 == b { y[$1] = $3 }
    END { for (r in x) if (r in y) printf "%.3f\n", x[r] / y[r] }' "$times" | spread
}
base_primary="quadtex primary closest-hit"
base_shadow="quadtex shadow any-hit BVH"
cpu=$(grep -m1 "model name" /proc/cpuinfo | sed 's/.*: *//')
echo
echo "## Terrain rays, ${width}x${height}: $(date -u +%Y-%m-%d), $cpu, $(nproc) cores (VM), $(uname -m); one thread each side; Embree $(dpkg-query -W -f='${Version}' libembree-dev 2>/dev/null || echo 3), build quality $quality; $rounds alternating rounds of $passes passes per method"
echo
echo "| side | rays | method | ns / ray, median (min–max) | Mrays/s | quadtex ÷ this, median (min–max) |"
echo "|---|---|---|---:|---:|---:|"
awk -F'\t' '!seen[$2]++ && $2 !~ /^build: / { print $2 }' "$times" | while IFS= read -r method; do
  case "$method" in quadtex*) side=quadtex ;; *) side=Embree ;; esac
  case "$method" in *" primary "*) kind=primary; base=$base_primary ;; *) kind=shadow; base=$base_shadow ;; esac
  read -r t_med t_min t_max < <(values "$method")
  label=${method#"$side "}
  label=${label#"$kind "}
  if [ "$side" = Embree ]; then
    read -r q_med q_min q_max < <(ratios "$base" "$method")
    ratio="$q_med ($q_min–$q_max)"
  elif [ "$method" = "$base" ]; then
    ratio="(quadtex's like-for-like $kind caster)"
  else
    read -r q_med q_min q_max < <(ratios "$method" "$base")
    ratio="$q_med ($q_min–$q_max) of the $kind line above"
  fi
  awk -v s="$side" -v k="$kind" -v m="$label" -v tm="$t_med" -v tl="$t_min" -v th="$t_max" -v q="$ratio" \
    'BEGIN { printf "| %s | %s | %s | %.1f (%.1f–%.1f) | %.2f | %s |\n", s, k, m, tm, tl, th, 1000 / tm, q }'
done
echo
echo "| BVH build (one thread) | ms, median (min–max) |"
echo "|---|---:|"
awk -F'\t' '!seen[$2]++ && $2 ~ /^build: / { print $2 }' "$times" | while IFS= read -r method; do
  read -r t_med t_min t_max < <(values "$method")
  awk -v m="${method#build: }" -v tm="$t_med" -v tl="$t_min" -v th="$t_max" \
    'BEGIN { printf "| %s | %.0f (%.0f–%.0f) |\n", m, tm, tl, th }'
done
echo
echo "Agreement with quadtex's answers (Embree on the f32 rounding of quadtex's f64 rays):"
echo
grep -v '^warning' "$out/embree-check.txt" | sed 's/^/    /'
echo
echo "(dump, answers and per-round times in $out)"
