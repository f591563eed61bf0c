#!/usr/bin/env bash
# Runs every fuzz target (or those named after SECONDS) for SECONDS seconds
# each (default 300) and prints the executions each survived. Needs
# cargo-fuzz (`cargo install cargo-fuzz --locked`);
# RUSTC_BOOTSTRAP lets the stable toolchain accept the sanitizer flags.
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-300}
shift || true
targets=${*:-qtx query_line integral scene svg obj exr}
export RUSTC_BOOTSTRAP=1
cargo fuzz build -O
for target in $targets; do
  mkdir -p "corpus/$target"
  seeds=""
  [ -d "seeds/$target" ] && seeds="seeds/$target"
  log="/tmp/quadtex-fuzz-$target.log"
  cargo fuzz run -O "$target" "corpus/$target" $seeds -- -max_total_time="$seconds" -print_final_stats=1 >"$log" 2>&1 || {
    echo "$target: FAILED, see $log and fuzz/artifacts/$target"; exit 1; }
  echo "$target: $(grep -m1 'stat::number_of_executed_units' "$log" | awk '{print $2}') executions in ${seconds}s, no finding"
done
