#!/usr/bin/env bash
# Runs every test of gantry. Idempotent: installs what it needs first.
# Usage: bash deploy/test.sh        (the README's test command; .ci/run calls it)
set -euo pipefail
cd "$(dirname "$0")/.."

if [ "${CI:-}" = "true" ]; then export CARGO_TERM_COLOR=never; fi
export CARGO_INCREMENTAL=0

step() {
  local name=$1; shift
  local t0=$SECONDS
  echo "==> $name"
  "$@"
  echo "<== $name ($((SECONDS - t0)) s)"
}

need_components() {
  # rustfmt and clippy come with the toolchain; add them when a minimal profile lacks them.
  for c in rustfmt clippy; do
    if ! cargo "${c/rustfmt/fmt}" --version >/dev/null 2>&1; then
      rustup component add "$c"
    fi
  done
}

need_packages() {
  # Debian packages the tests call: tshark checks our pcap files with Wireshark's dissector;
  # ip (iproute2) makes the network namespaces and veth pairs of the real-time tests.
  local missing=()
  command -v tshark >/dev/null 2>&1 || missing+=(tshark)
  command -v ip >/dev/null 2>&1 || missing+=(iproute2)
  # cyclictest: gantry rt-check measures beside it; ethtool: NIC coalescing check;
  # setpriv: the tests that run gantry without capabilities, and with the unit's.
  command -v cyclictest >/dev/null 2>&1 || missing+=(rt-tests)
  command -v ethtool >/dev/null 2>&1 || missing+=(ethtool)
  command -v setpriv >/dev/null 2>&1 || missing+=(util-linux)
  # systemd-analyze: the test that systemd accepts deploy/gantry.service.
  command -v systemd-analyze >/dev/null 2>&1 || missing+=(systemd)
  # cansend: the vcan tests send a 29-bit frame with it (in the VM it is the host's too).
  command -v cansend >/dev/null 2>&1 || missing+=(can-utils)
  # python3 with venv (ensurepip) runs the SOEM test peer (tests/peers/).
  command -v python3 >/dev/null 2>&1 || missing+=(python3)
  python3 -c "import ensurepip" >/dev/null 2>&1 || missing+=(python3-venv)
  if [ ${#missing[@]} -gt 0 ]; then
    local sudo=""
    [ "$(id -u)" = 0 ] || sudo="sudo"
    echo "wireshark-common wireshark-common/install-setuid boolean false" | $sudo debconf-set-selections
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}"
  fi
}

need_peer() {
  # SOEM as a second, independent EtherCAT master (tests/tests/peer_soem.rs): the pysoem
  # wheel in a venv of its own, run as a separate process — SOEM is GPL and is never
  # linked into gantry. python-canopen (with python-can) likewise as a CANopen master
  # (tests/tests/vcan_peer_canopen.rs). Made once; the tests find its python in
  # GANTRY_PEER_PYTHON.
  local venv="$HOME/.cache/gantry/venv"
  local py="$venv/bin/python"
  local pkg version
  for pkg in pysoem==1.1.10 canopen==2.4.1; do
    version=${pkg#*==}
    if ! "$py" -c "import importlib.metadata as m, sys; sys.exit(m.version('${pkg%==*}') != '$version')" >/dev/null 2>&1; then
      [ -x "$py" ] || python3 -m venv "$venv"
      "$py" -m pip install --quiet --disable-pip-version-check "$pkg"
    fi
  done
  export GANTRY_PEER_PYTHON="$py"
}

host_has_vcan() {
  # Whether this kernel makes vcan interfaces (tried in a throw-away network namespace).
  [ "$(id -u)" = 0 ] || return 1
  modprobe vcan >/dev/null 2>&1 || true
  ip netns add gantry-vcan-probe >/dev/null 2>&1 || return 1
  local ok=1
  ip -n gantry-vcan-probe link add dev vcan0 type vcan >/dev/null 2>&1 && ok=0
  ip netns del gantry-vcan-probe
  return $ok
}

vcan_tests() {
  # The SocketCAN tests (tests/tests/vcan_*.rs, feature `vcan`): built here in release,
  # run where vcan0 and vcan1 exist — in a network namespace of this host if its kernel
  # has vcan, else all in one boot of the PREEMPT_RT VM of deploy/vm/ (the build
  # machines' kernels have no CAN). The VM passes no environment: it is written into the
  # command.
  local bins
  bins=$(cargo test -p gantry-tests --release --features vcan --test 'vcan_*' --no-run \
           --message-format=json \
         | python3 -c 'import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and "test" in m["target"]["kind"]:
        print(m["executable"])')
  [ -n "$bins" ] || { echo "no vcan test binaries built" >&2; return 1; }
  local cmd="failed=0; for t in $(echo $bins); do GANTRY_PEER_PYTHON=$GANTRY_PEER_PYTHON \$t || failed=1; done; exit \$failed"
  if host_has_vcan; then
    ip netns del gantry-vcan >/dev/null 2>&1 || true
    ip netns add gantry-vcan
    local i
    for i in 0 1; do
      ip -n gantry-vcan link add dev vcan$i type vcan
      ip -n gantry-vcan link set vcan$i up
    done
    local rc=0
    ip netns exec gantry-vcan sh -c "$cmd" || rc=$?
    ip netns del gantry-vcan
    return $rc
  fi
  bash deploy/vm/run --self-test
  bash deploy/vm/run --timeout 1800 "$cmd"
}

step "toolchain components" need_components
step "packages" need_packages
step "SOEM test peer (pysoem venv)" need_peer
step "fmt" cargo fmt --all -- --check
step "clippy" cargo clippy --workspace --all-targets --release --features gantry-tests/vcan -- -D warnings
step "binaries" cargo build --workspace --release --bins
step "tests" cargo test --workspace --release -- --include-ignored
step "vcan tests (deploy/vm)" vcan_tests
step "benches compile" cargo bench --workspace --no-run
