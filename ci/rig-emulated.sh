#!/usr/bin/env bash
# The main job: the full rig suite on the emulated rig (pty pairs, emulated
# MultiRX, Python fixtures). Prints a summary and where the report is.
# Extra arguments go to `rig run` (e.g. --filter parallel::b_handover).
set -euo pipefail
cd "$(dirname "$0")/.."
bash ci/setup.sh
echo "rig: building (release)..."
cargo build --release --locked -q -p harness -p multirx-emulator -p mavlora --bins
exec target/release/rig run rigs/emulated.toml "$@"
