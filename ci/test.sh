#!/usr/bin/env bash
# Every test: formatting and lints, the Rust workspace (unit, property,
# scenario and end-to-end tests over real ptys), the Python fixtures, the
# SAMD21 firmware build with its size and its cycle budget (instruction counts
# of the core for thumbv6m under QEMU: ci/cycle-budget.py), the MultiRX core's and MavLora's
# benchmarks, and the full emulated rig suite. Each step says when it
# started (seconds since the first).
#
# One build serves tests, benchmarks and the rig: everything is built once in
# the release profile (benchmarks and the rig's real-time phases need it), so
# the 2-core CI machine compiles the dependency tree once instead of twice
# (`--workspace` everywhere: one feature set, so nothing compiles again). That set
# leaves out the rig's `flash` feature: probe-rs is a third of the build, and the
# emulated rig flashes nothing (the lints below still check that code).
#
# Lints: the release build itself runs clippy on the workspace's crates (clippy-driver as
# cargo's RUSTC_WORKSPACE_WRAPPER, which is all `cargo clippy` does, plus code generation),
# with -D warnings, for every target it builds (`--all-targets`, as `cargo clippy
# --all-targets`). A separate `cargo clippy` compiled the whole dependency tree a second
# time (~200 s of CPU, a third of the 2-core budget). What that feature set leaves out
# (the rig's `flash` code) is linted by `cargo clippy --workspace --all-targets` on a
# developer's machine.
#
# Order, for the wall time: the rig suite spends its ~4.5 minutes waiting on
# real time (fixtures pace frames at 7 ms, scans wait out 2 s windows) and uses
# about a third of the CPU. So the programs it runs are built first, then the
# suite runs while the test binaries and benchmarks build beside it in the idle scheduling
# class, niced (it yields a core to any other process that wakes; the MultiRX
# emulator's measured thread is SCHED_FIFO where allowed, and its gaps are read
# on the device's clock). The tests run after the suite, on a quiet machine.
# The real-time MavLora scenarios run once, as rig phases; their `cargo test`
# twins (harness/tests/mavlora_realtime.rs, the same scenarios through the same
# code) are filtered out here and run by a plain `cargo test --workspace` on a
# developer's machine.
set -euo pipefail
cd "$(dirname "$0")/.."
bash ci/setup.sh

# The one feature set of the build, the tests and the benchmarks.
features=(--no-default-features --features mavlora/cli)

started=$SECONDS
step() { printf '\n=== %s (at %d s)\n' "$*" $((SECONDS - started)); }

step "cargo fmt --check"
cargo fmt --all -- --check
# Every cargo build below lints as it compiles (see above); nothing else may see the wrapper:
# the firmware's own workspace, the rig and the test programs get a clean environment.
export RUSTC_WORKSPACE_WRAPPER=clippy-driver
export CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__"
# No line tables in CI's build: less to generate and link for ~40 binaries, on a machine
# short of CPU. A failing assertion still names its file and line; only backtraces lose them.
export CARGO_PROFILE_RELEASE_DEBUG=false
unlinted=(env -u RUSTC_WORKSPACE_WRAPPER -u CLIPPY_ARGS -u CARGO_PROFILE_RELEASE_DEBUG)
mkdir -p target
step "build the programs the rig runs (release; clippy -D warnings on the workspace's crates)"
# `--test model` (harness-radio's, a small one): with one target that needs the dev-dependencies,
# cargo resolves features with them for the whole build, as the test build below will. Without
# it the programs' rustix, num-traits, rand and regex-syntax got other features than the tests',
# so the test build compiled them again with everything above them (mavlink, the generated
# dialect, tracing-subscriber, every workspace crate). The programs are then also built exactly
# as the tests see them.
cargo build --release --locked --workspace --bins --test model "${features[@]}"
# The rest of `--all-targets` (test binaries, benchmarks) shares every unit just built.
# Niced, not SCHED_IDLE: an idle-class linker that holds a kernel lock (a file system's,
# the page cache's) while every core has other work is not run again for seconds, and
# whoever waits on that lock waits with it: twice a 3 s stall of every fixture at once
# during the final link (both realtime::ardupilot bridges saw their autopilot "reboot" at
# the same instant). The MultiRX fixtures that once needed the idle class to keep their
# 7 ms cadence run SCHED_FIFO themselves now (fixtures/sbus_receiver.py).
background="nice -n 19"
step "build the tests, benchmarks and firmware, and measure the firmware's cycle budget (in the background, $background; logs: target/test-build.log, target/firmware-build.log)"
$background cargo build --release --locked --workspace --all-targets "${features[@]}" \
    > target/test-build.log 2>&1 &
test_build_pid=$!
# The firmware's own workspace and target (thumbv6m): its build and size checks, then the
# core's cycle budget (its own thumbv6m crate, run on QEMU). Instruction counts do not depend
# on how busy the machine is, so it runs niced beside the suite too.
$background "${unlinted[@]}" bash -c 'bash ci/build-firmware.sh && python3 ci/cycle-budget.py' \
    > target/firmware-build.log 2>&1 &
firmware_pid=$!
trap 'kill "$test_build_pid" "$firmware_pid" 2>/dev/null || true' EXIT
# Real autopilots (the sitl suite, the SITL driver and fixture tests) come from ../shared
# next to the checkout, where rigs/emulated.toml looks. Found, every SITL test must run
# (C2_REQUIRE_SITL): a lookup that silently finds nothing would pass by doing nothing.
shared="$(cd .. && pwd)/shared"
if [ -x "$shared/ardupilot-sitl/arducopter" ] && [ -x "$shared/px4-sitl/bin/px4" ]; then
    export C2_REQUIRE_SITL=1
    echo "SITL builds: $shared/ardupilot-sitl, $shared/px4-sitl"
else
    echo "WARNING: no ArduPilot/PX4 SITL builds in $shared: the sitl suite's phases are" \
        "reported as skipped and the SITL tests do not run (see ../shared/*/README.md)" >&2
fi
step "rig suite, emulated rig (includes the real-time MavLora scenarios and the sitl suite)"
RIG_PREBUILT=1 "${unlinted[@]}" bash ci/rig-emulated.sh --out target/rig-report
step "firmware build, size and cycle budget (built and measured beside the suite)"
status=0
wait "$firmware_pid" || status=$?
cat target/firmware-build.log
[ "$status" -eq 0 ] || { echo "the firmware build, its checks or its cycle budget failed (log above)" >&2; exit 1; }
# The fixtures' tests need no build: they run while the tests' build finishes, niced, beside
# them. Four workers on two cores: they mostly wait on real time (subprocesses, ptys,
# sockets); one after another they took 72 s, side by side 23 s.
step "pytest fixtures (4 workers)"
"${unlinted[@]}" python3 -m pytest -q -n 4 fixtures/tests
step "build the tests and benchmarks: waiting for it"
if ! wait "$test_build_pid"; then
    cat target/test-build.log
    echo "building the tests failed (log above)" >&2
    exit 1
fi
step "cargo test --workspace (release; test binaries four at a time: ci/run-tests.sh)"
bash ci/run-tests.sh "${features[@]}" -- \
    --skip table_ii_compact_and_limit_filter_bandwidth \
    --skip mission_upload_over_lossy_sik_arrives_intact \
    --skip c2_latency_over_lossy_sik
step "multirx-core benchmark"
cargo bench --locked -q --workspace "${features[@]}" --bench mux
step "mavlora benchmark"
cargo bench --locked -q --workspace "${features[@]}" --bench radio
# 3 replays (63 k frames) and 3 s idle here, for CI's 10 minutes; the defaults (60 replays,
# 10 s) for the record. The MavLora benchmarks are harness-sim's (they replay its simulated
# flights); router_cost runs the mavlora-router and mavlora-bridge of the first build above,
# from target/release/.
step "mavlora-router cost per frame, memory and idle CPU, against a sendto-per-frame baseline"
MAVLORA_BENCH_ROUNDS=3 MAVLORA_BENCH_IDLE_S=3 \
    cargo bench --locked -q --workspace "${features[@]}" --bench router_cost
step "done"
