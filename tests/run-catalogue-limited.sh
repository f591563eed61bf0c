#!/usr/bin/env bash
# Runs the bad-input catalogue (tests/bad_inputs.rs) under a 4 GiB
# address-space limit (`ulimit -v`), as CI does: every hostile input must be
# refused within it, so an allocation sized by a lying header fails the test
# instead of passing on an overcommitting machine. Cargo and rustc need more
# address space than that, so the test binary is built first and run alone
# under the limit, in a subshell. Extra arguments go to the test binary
# (a name filter, --nocapture). LIMIT_KIB overrides the limit (KiB).
set -euo pipefail
cd "$(dirname "$0")/.."
limit=${LIMIT_KIB:-4194304}
# The test binary and the `quadtex` binary it runs (both built here).
bin=$(cargo test --no-run --test bad_inputs --message-format=json 2>/dev/null |
  sed -n 's/.*"executable":"\([^"]*\/bad_inputs-[^"]*\)".*/\1/p' | tail -n 1)
[ -x "$bin" ] || { echo "run-catalogue-limited: bad_inputs test binary not found" >&2; exit 1; }
echo "running $bin under ulimit -v $limit"
(ulimit -v "$limit" && "$bin" "$@")
