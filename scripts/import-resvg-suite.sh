#!/usr/bin/env bash
# Copies the SVG conformance tests quadtex checks itself against from a
# checkout of linebender/resvg into tests/resvg-suite/ (SVGs and resvg's
# reference PNGs, 300 px wide; licence alongside). The pinned commit is the
# one the committed copy came from; CI does not run this (no network).
#
#   scripts/import-resvg-suite.sh /path/to/resvg [COMMIT]
set -euo pipefail
src=${1:?usage: $0 RESVG_CHECKOUT [COMMIT]}
commit=${2:-08c79a31}
dest="$(cd "$(dirname "$0")/.." && pwd)/tests/resvg-suite"
categories=(shapes structure painting masking paint-servers)
rm -rf "$dest"
mkdir -p "$dest"
mkdir -p "$dest/tests" "$dest/resources"
for c in "${categories[@]}"; do
  git -C "$src" archive "$commit" "crates/resvg/tests/tests/$c" | tar -x -C "$dest/tests" --strip-components=4
done
# The images the tests refer to as ../../../resources/.
git -C "$src" archive "$commit" crates/resvg/tests/resources | tar -x -C "$dest/resources" --strip-components=4
git -C "$src" show "$commit:LICENSE-MIT" >"$dest/LICENSE-MIT"
cat >"$dest/README.md" <<TXT
# resvg's SVG test suite (subset)

The \`shapes\`, \`structure\`, \`painting\`, \`masking\` and \`paint-servers\`
folders of \`crates/resvg/tests/tests\` (in \`tests/\`, with the images they
refer to from \`crates/resvg/tests/resources\` in \`resources/\`) in linebender/resvg at commit
\`$(git -C "$src" rev-parse "$commit")\`: each SVG with the PNG resvg renders
of it (300 px wide). Copyright the resvg authors, MIT licence (LICENSE-MIT).
Imported by \`scripts/import-resvg-suite.sh\`; checked by \`tests/resvg_suite.rs\`.
TXT
echo "$(find "$dest" -name '*.svg' | wc -l) SVGs in $dest"
