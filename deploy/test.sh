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

step "toolchain components" need_components
step "fmt" cargo fmt --all -- --check
step "clippy" cargo clippy --workspace --all-targets --release -- -D warnings
step "tests" cargo test --workspace --release
step "benches compile" cargo bench --workspace --no-run
