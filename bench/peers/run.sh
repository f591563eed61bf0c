#!/usr/bin/env bash
# quadtex against OpenImageIO's TextureSystem on the same footprints, in one
# run: builds both sides, dumps the scene's footprints, then times each
# side's lookups (one thread, filtering only) in alternating rounds (the
# order flips every round, so drift of the machine hits both sides alike),
# and prints one table: per method the median ns per lookup with its
# min–max over the rounds, error against a supersampled reference of the
# scene's textures, and the time ratio to OIIO's anisotropic filter with
# its spread (min–max of the per-round ratios).
#
# Usage: bash bench/peers/run.sh SCENE.toml [WIDTH] [PASSES] [ROUNDS]
#   PASSES: timing passes per side per round (each side reports its median)
#   ROUNDS: alternating rounds (at least 5)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
scene=${1:?usage: run.sh SCENE.toml [WIDTH] [PASSES] [ROUNDS]}
width=${2:-480}
passes=${3:-3}
rounds=${4:-7}
[ "$rounds" -ge 5 ] || { echo "run.sh: ROUNDS must be at least 5" >&2; exit 2; }
bash "$root/bench/peers/oiio/install.sh"
cargo build --release --quiet --manifest-path "$root/Cargo.toml"
qt="$root/target/release/quadtex"
mkdir -p "$root/target/peers"
g++ -O2 -std=c++17 -o "$root/target/peers/oiio_lookup" "$root/bench/peers/oiio/oiio_lookup.cpp" \
  $(pkg-config --cflags --libs OpenImageIO)
oiio="$root/target/peers/oiio_lookup"
out="$root/target/peers/$(basename "$scene" .toml)"
mkdir -p "$out"
# The dump, the reference and each side's images (one timing pass: not used).
"$qt" footprints "$scene" -o "$out" --width "$width" --passes 1 >&2
"$oiio" "$out" 1 >"$out/oiio.tsv" 2>"$out/oiio-stats.txt"
peak=$(grep -m1 "Peak cache memory" "$out/oiio-stats.txt" | sed 's/.*: *//')
# Alternating rounds: "round<TAB>method<TAB>ns" lines for both sides.
times="$out/rounds.tsv"
: >"$times"
for round in $(seq 1 "$rounds"); do
  quadtex_side() {
    "$qt" footprints "$scene" -o "$out" --width "$width" --passes "$passes" --timing-only |
      awk -F'\t' -v r="$round" '{ print r "\t" $1 "\t" $2 }' >>"$times"
  }
  oiio_side() {
    "$oiio" "$out" "$passes" 2>/dev/null | tail -n +2 |
      awk -F'\t' -v r="$round" '{ print r "\t" $1 "\t" $2 }' >>"$times"
  }
  if [ $((round % 2)) -eq 1 ]; then quadtex_side; oiio_side; else oiio_side; quadtex_side; fi
  echo "round $round of $rounds done" >&2
done
echo
echo "## $(basename "$scene"): ${width}px wide, $(date -u +%Y-%m-%d), $(nproc) cores, $(uname -m); lookups on one thread; $rounds alternating rounds of $passes passes per side"
echo
echo "| method | ns / lookup, median (min–max) | texture memory | RMSE | FLIP | time vs OIIO aniso 16, median (min–max) | RMSE vs OIIO aniso 16 |"
echo "|---|---:|---:|---:|---:|---:|---:|"
base_method="OIIO aniso 16 bilinear"
# "median min max" of a column of numbers on stdin (POSIX tools only).
spread() {
  sort -g | awk '{ v[NR] = $1 } END { printf "%s %s %s\n", v[int((NR + 1) / 2)], v[1], v[NR] }'
}
# Per method: the spread of its per-round ns, then of its per-round ratio
# to the base method's time in the same round.
stats() {
  local t q
  t=$(awk -F'\t' -v m="$1" '$2 == m { printf "%.0f\n", $3 }' "$times" | spread)
  q=$(awk -F'\t' -v m="$1" -v b="$base_method" '
    $2 == b { base[$1] = $3 } $2 == m { ns[$1] = $3 }
    END { for (r in ns) printf "%.2f\n", ns[r] / base[r] }' "$times" | spread)
  echo "$t $q"
}
base_rmse=""
rows=$(mktemp)
for tsv in "$out/quadtex.tsv" "$out/oiio.tsv"; do
  tail -n +2 "$tsv" | while IFS=$'\t' read -r method _ bytes file; do
    read -r _ rmse _ flip < <("$qt" diff "$out/reference.exr" "$out/$file")
    memory=$(awk -v b="$bytes" 'BEGIN { if (b < 1048576) printf "%.1f KiB", b / 1024; else printf "%.2f MiB", b / 1048576 }')
    case "$method" in OIIO*) memory="$memory .tx, cache peak $peak" ;; esac
    printf '%s\t%s\t%s\t%s\n' "$method" "$memory" "$rmse" "$flip" >>"$rows"
  done
done
base_rmse=$(awk -F'\t' -v b="$base_method" '$1 == b { print $3 }' "$rows")
while IFS=$'\t' read -r method memory rmse flip; do
  read -r t_med t_min t_max q_med q_min q_max < <(stats "$method")
  awk -v m="$method" -v mem="$memory" -v r="$rmse" -v f="$flip" -v br="$base_rmse" \
    -v tm="$t_med" -v tl="$t_min" -v th="$t_max" -v qm="$q_med" -v ql="$q_min" -v qh="$q_max" \
    'BEGIN { printf "| %s | %s (%s–%s) | %s | %.4f | %.4f | %s (%s–%s) | %.2f |\n", m, tm, tl, th, mem, r, f, qm, ql, qh, r / br }'
done <"$rows"
rm -f "$rows"
echo
echo "(RMSE and FLIP against $out/reference.exr: the scene's textures alone, supersampled; images and .tx files in $out; per-round times in $times)"
