#!/usr/bin/env bash
# Wake-up latency of gantry's cycle thread against cyclictest at the same priority, in the
# same run, at 1 kHz and 4 kHz (the README's figures). Needs root or CAP_SYS_NICE and
# rt-tests (cyclictest). Usage: bash deploy/bench-latency.sh [seconds]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-10}
cargo build --release -p gantry-cli --bin gantry >/dev/null
for cycle in 1000 250; do
  echo "== cycle ${cycle} µs"
  ./target/release/gantry rt-check --cycle-us "$cycle" --seconds "$seconds" | tail -4
done
