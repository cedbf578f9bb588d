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
  # linked into gantry. Made once; the test finds its python in GANTRY_PEER_PYTHON.
  local venv="$HOME/.cache/gantry/venv" version=1.1.10
  local py="$venv/bin/python"
  if ! "$py" -c "import importlib.metadata as m, sys; sys.exit(m.version('pysoem') != '$version')" >/dev/null 2>&1; then
    [ -x "$py" ] || python3 -m venv "$venv"
    "$py" -m pip install --quiet --disable-pip-version-check "pysoem==$version"
  fi
  export GANTRY_PEER_PYTHON="$py"
}

step "toolchain components" need_components
step "packages" need_packages
step "SOEM test peer (pysoem venv)" need_peer
step "fmt" cargo fmt --all -- --check
step "clippy" cargo clippy --workspace --all-targets --release -- -D warnings
step "binaries" cargo build --workspace --release --bins
step "tests" cargo test --workspace --release -- --include-ignored
step "benches compile" cargo bench --workspace --no-run
