#!/usr/bin/env bash
# Every test: formatting and lints, the Rust workspace (unit, property,
# scenario and end-to-end tests over real ptys), the Python fixtures, the
# SAMD21 firmware build with its size, the MultiRX core's and MavLora's
# benchmarks, and finally the full emulated rig suite. Each step says when it
# started (seconds since the first).
set -euo pipefail
cd "$(dirname "$0")/.."
bash ci/setup.sh

started=$SECONDS
step() { printf '\n=== %s (at %d s)\n' "$*" $((SECONDS - started)); }

step "cargo fmt --check"
cargo fmt --all -- --check
step "cargo clippy -D warnings"
cargo clippy --locked --workspace --all-targets -- -D warnings
step "cargo test --workspace"
cargo test --locked --workspace
step "pytest fixtures"
python3 -m pytest -q fixtures/tests
step "firmware build and size"
bash ci/build-firmware.sh
step "multirx-core benchmark"
cargo bench --locked -q -p multirx-core --bench mux
step "mavlora benchmark"
cargo bench --locked -q -p mavlora --bench radio
step "rig suite, emulated rig"
bash ci/rig-emulated.sh --out target/rig-report
step "done"
