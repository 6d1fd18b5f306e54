#!/usr/bin/env bash
# The main job: the full rig suite on the emulated rig (pty pairs, emulated
# MultiRX, Python fixtures). Prints a summary and where the report is.
# Extra arguments go to `rig run` (e.g. --filter parallel::b_handover).
set -euo pipefail
cd "$(dirname "$0")/.."
bash ci/setup.sh
# Not -q: on a fresh machine the build takes minutes, and cargo's progress
# line is the only sign of life. RIG_PREBUILT=1: the caller (ci/test.sh)
# has just built these programs with everything else.
if [ -z "${RIG_PREBUILT:-}" ]; then
    echo "rig: building the rig, multirx-emu, mavlora-bridge and mavlora-router (release)..."
    cargo build --release --locked --workspace --bins
fi
exec target/release/rig run rigs/emulated.toml "$@"
