#!/usr/bin/env bash
# Wake-up latency of gantry's cycle thread against cyclictest at the same priority, in the
# same run, at 1 kHz and 4 kHz (the README's figures). With --can: when the CANopen cycle
# thread hands each SYNC to its link (4 simulated servos at 2 ms, 8 at 4 ms, in memory at
# 1 Mbit/s: no CAN hardware), against cyclictest pinned to the same CPU.
# Needs root or CAP_SYS_NICE (+ CAP_IPC_LOCK) and rt-tests (cyclictest).
# Usage: bash deploy/bench-latency.sh [--can] [seconds]
set -euo pipefail
cd "$(dirname "$0")/.."
can=0
if [ "${1:-}" = "--can" ]; then
  can=1
  shift
fi
seconds=${1:-10}
cargo build --release -p gantry-cli --bin gantry >/dev/null
gantry=${CARGO_TARGET_DIR:-target}/release/gantry
if [ "$can" = 1 ]; then
  for run in "4 2000" "8 4000"; do
    set -- $run
    echo "== CANopen SYNC, $1 drives, cycle $2 µs"
    "$gantry" rt-check --can "$1" --cycle-us "$2" --seconds "$seconds" | sed -n '/^SYNC of/,$p'
  done
  exit 0
fi
for cycle in 1000 250; do
  echo "== cycle ${cycle} µs"
  "$gantry" rt-check --cycle-us "$cycle" --seconds "$seconds" | tail -4
done
