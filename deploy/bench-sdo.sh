#!/usr/bin/env bash
# The SDO benchmark of the CANopen issue: a 64 KiB upload (the simulated node's recorder
# 0x2F00) by gantry's SDO client and by python-canopen's, on the same gantry-sim node over
# vcan, in one run (tests/tests/sdo_bench_vcan.rs). Prints the "SDO bench:" figures.
# Runs in a network namespace where the host kernel has vcan, else in the VM of deploy/vm/
# (the build machines' kernels have no CAN; there the figures are an emulator's).
# Usage: bash deploy/bench-sdo.sh   (not part of deploy/test.sh: ten minutes in an emulated VM)
set -euo pipefail
cd "$(dirname "$0")/.."

venv="$HOME/.cache/gantry/venv"
py="$venv/bin/python"
if ! "$py" -c "import importlib.metadata as m, sys; sys.exit(m.version('canopen') != '2.4.1')" >/dev/null 2>&1; then
  [ -x "$py" ] || python3 -m venv "$venv"
  "$py" -m pip install --quiet --disable-pip-version-check canopen==2.4.1
fi

cargo build --release -p gantry-sim --bin gantry-sim
bin=$(cargo test -p gantry-tests --release --features vcan --test sdo_bench_vcan --no-run \
        --message-format=json \
      | python3 -c 'import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and "test" in m["target"]["kind"]:
        print(m["executable"])')
[ -n "$bin" ] || { echo "sdo_bench_vcan was not built" >&2; exit 1; }
cmd="GANTRY_PEER_PYTHON=$py $bin --nocapture >/tmp/gantry-sdo-bench.log 2>&1; rc=\$?; grep -E 'SDO bench|panicked|test result' /tmp/gantry-sdo-bench.log; exit \$rc"

if [ "$(id -u)" = 0 ] && modprobe vcan >/dev/null 2>&1 && ip netns add gantry-sdo-bench >/dev/null 2>&1; then
  trap 'ip netns del gantry-sdo-bench' EXIT
  for i in 0 1; do
    ip -n gantry-sdo-bench link add dev vcan$i type vcan
    ip -n gantry-sdo-bench link set vcan$i up
  done
  ip netns exec gantry-sdo-bench sh -c "$cmd"
else
  bash deploy/vm/run --timeout 1800 "$cmd"
fi
