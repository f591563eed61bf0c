#!/usr/bin/env bash
# quadtex against OpenImageIO's TextureSystem on the same footprints, in one
# run: builds both sides, dumps the scene's footprints, times each side's
# lookups (one thread, filtering only), and prints one table with error
# against a supersampled reference of the scene's textures.
#
# Usage: bash bench/peers/run.sh SCENE.toml [WIDTH] [PASSES]
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
scene=${1:?usage: run.sh SCENE.toml [WIDTH] [PASSES]}
width=${2:-480}
passes=${3:-5}
bash "$root/bench/peers/oiio/install.sh"
cargo build --release --quiet --manifest-path "$root/Cargo.toml"
qt="$root/target/release/quadtex"
mkdir -p "$root/target/peers"
g++ -O2 -std=c++17 -o "$root/target/peers/oiio_lookup" "$root/bench/peers/oiio/oiio_lookup.cpp" \
  $(pkg-config --cflags --libs OpenImageIO)
out="$root/target/peers/$(basename "$scene" .toml)"
mkdir -p "$out"
"$qt" footprints "$scene" -o "$out" --width "$width" --passes "$passes" >&2
"$root/target/peers/oiio_lookup" "$out" "$passes" >"$out/oiio.tsv" 2>"$out/oiio-stats.txt"
peak=$(grep -m1 "Peak cache memory" "$out/oiio-stats.txt" | sed 's/.*: *//')
echo
echo "## $(basename "$scene"): ${width}px wide, $(date -u +%Y-%m-%d), $(nproc) cores, $(uname -m); lookups on one thread, median of $passes passes"
echo
echo "| method | ns / lookup | texture memory | RMSE | FLIP | time vs OIIO aniso 16 | RMSE vs OIIO aniso 16 |"
echo "|---|---:|---:|---:|---:|---:|---:|"
rows=$(mktemp)
for tsv in "$out/quadtex.tsv" "$out/oiio.tsv"; do
  tail -n +2 "$tsv" | while IFS=$'\t' read -r method ns bytes file; do
    read -r _ rmse _ flip < <("$qt" diff "$out/reference.exr" "$out/$file")
    memory=$(awk -v b="$bytes" 'BEGIN { if (b < 1048576) printf "%.1f KiB", b / 1024; else printf "%.2f MiB", b / 1048576 }')
    case "$method" in OIIO*) memory="$memory .tx, cache peak $peak" ;; esac
    printf '%s\t%s\t%s\t%s\t%s\n' "$method" "$ns" "$memory" "$rmse" "$flip" >>"$rows"
  done
done
base=$(awk -F'\t' '$1 == "OIIO aniso 16 bilinear" { print $2 "\t" $4 }' "$rows")
awk -F'\t' -v base="$base" 'BEGIN { split(base, b, "\t") }
  { printf "| %s | %.0f | %s | %.4f | %.4f | %.2f | %.2f |\n", $1, $2, $3, $4, $5, $2 / b[1], $4 / b[2] }' "$rows"
rm -f "$rows"
echo
echo "(RMSE and FLIP against $out/reference.exr: the scene's textures alone, supersampled; images and .tx files in $out)"
