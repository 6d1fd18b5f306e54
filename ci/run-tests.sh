#!/usr/bin/env bash
# Runs the workspace's test binaries (already built in release), four at a
# time, each in its package's folder as `cargo test` would, then the doc tests.
#
# `cargo test` runs one test binary after another; most of ours wait on real
# time (end-to-end runs over ptys, a 12 s scripted link cut): on a 2-core
# machine all of them together use 84 s of CPU in 94 s two at a time, so four
# side by side still leave the CPU idle part of the time and take half the wall
# time. RUN_TESTS_LANES sets how many (4).
# Each binary's output goes to target/test-logs/<name>.log and is printed when
# it fails; a summary line per binary says how long it took.
#
# Usage: ci/run-tests.sh [CARGO ARGS...] -- [TEST ARGS...]
#   e.g. ci/run-tests.sh --no-default-features --features mavlora/cli -- --skip slow_one
set -euo pipefail
cd "$(dirname "$0")/.."

cargo_args=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do
    cargo_args+=("$1")
    shift
done
[ "${1:-}" = "--" ] && shift
test_args=("$@")

logs=target/test-logs
rm -rf "$logs"
mkdir -p "$logs"

# Every test executable with its package folder, from cargo's own build plan.
cargo test --release --locked --workspace "${cargo_args[@]}" --no-run --message-format=json \
    | python3 -c '
import json, os, sys
found = []
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["profile"]["test"]:
        found.append((os.path.dirname(m["manifest_path"]), m["executable"], m["target"]["name"]))
# The long real-time ones first, so the lanes end together.
slow = ("e2e_", "firmware", "cli")
found.sort(key=lambda f: not f[2].startswith(slow))
# Alone, after the lanes, with no other test on the CPU: the emulated MultiRX device, tested
# against host holds (SIGSTOP) to the millisecond; the rig program running real-time MultiRX
# phases (harness/tests/cli.rs: beside three other lanes it once saw 17 idle takeovers); and
# the router test that the number of a vanished radio pty, reused by the kernel for an
# unrelated pty, is not reopened (beside other tests that make ptys, one took it first).
alone = lambda d, name: (
    d.endswith("firmware/multirx/emulator")
    or (d.endswith("/harness") and name == "cli")
    or name == "cli_reopen"
)
with open(sys.argv[1], "w") as lanes, open(sys.argv[2], "w") as solo:
    for d, exe, name in found:
        (solo if alone(d, name) else lanes).write(d + "\t" + exe + "\n")
' "$logs/binaries.tsv" "$logs/alone.tsv"
lanes=${RUN_TESTS_LANES:-4}
echo "run-tests: $(wc -l < "$logs/binaries.tsv") test binaries $lanes at a time, then $(wc -l < "$logs/alone.tsv") alone (logs: $logs/)"
lanes_started=$SECONDS

run_one() {
    local dir=$1 exe=$2 name started status extra
    read -ra extra <<< "$RUN_TESTS_ARGS"
    name=$(basename "$exe")
    started=$SECONDS
    status=0
    # A test that runs cargo itself (the firmware build) builds as ci/build-firmware.sh did:
    # ci/test.sh's lint wrapper and profile setting are for the build of these binaries only
    # (with them, the firmware test rebuilt the firmware's dependencies: 56 s in a lane).
    (cd "$dir" && env -u RUSTC_WORKSPACE_WRAPPER -u CLIPPY_ARGS -u CARGO_PROFILE_RELEASE_DEBUG \
        "$exe" "${extra[@]}") \
        > "$logs/$name.log" 2>&1 || status=$?
    if [ "$status" -ne 0 ]; then
        cat "$logs/$name.log"
        echo "run-tests: FAILED $name (exit $status, $((SECONDS - started)) s, log $logs/$name.log)"
        return 1
    fi
    echo "run-tests: ok $name ($((SECONDS - started)) s; $(grep -h '^test result' "$logs/$name.log" | tail -1))"
    # What the fuzz-corpus replays covered (inputs, seconds: tests/fuzz_corpus.rs).
    grep -o 'fuzz-corpus: .*' "$logs/$name.log" | sed 's/^/run-tests:   /' || true
}
export -f run_one
export logs
# Test arguments never hold spaces (test names, flags): one string through xargs.
export RUN_TESTS_ARGS="${test_args[*]}"

# xargs exits non-zero when any run failed, after all have run.
tr '\t' '\n' < "$logs/binaries.tsv" \
    | xargs -d '\n' -n 2 -P "$lanes" bash -c 'run_one "$@"' _ \
    || { echo "run-tests: some test binaries failed (above)" >&2; exit 1; }
tr '\t' '\n' < "$logs/alone.tsv" \
    | xargs -d '\n' -n 2 -P 1 bash -c 'run_one "$@"' _ \
    || { echo "run-tests: a test binary run alone failed (above)" >&2; exit 1; }
echo "run-tests: every binary passed in $((SECONDS - lanes_started)) s"

cargo test --release --locked --workspace "${cargo_args[@]}" --doc -q
