#!/usr/bin/env bash
# Runs every cargo-fuzz target of the three fuzz crates for FUZZ_SECONDS each (default 20),
# starting from the corpus kept in the repository. A crash, a failed invariant (assert) or a
# leak fails the script, naming the target; the input that did it is under the crate's
# fuzz/artifacts/<target>/.
#
# Needs the nightly toolchain (sanitizers) and cargo-fuzz: installs cargo-fuzz from crates.io
# if it is missing. Long runs: FUZZ_SECONDS=600 bash ci/fuzz.sh
#
# Not part of CI (ci/test.sh): nightly and sanitizer builds do not fit its time. What CI checks
# instead, on stable, with the same code: each target's body lives in
# <crate>/fuzz/bodies/<target>.rs, which both fuzz_targets/<target>.rs (libFuzzer) and the
# crate's tests/fuzz_corpus.rs (an ordinary test binary) compile. That test replays every file
# of fuzz/corpus/<target>/ and fuzz/artifacts/<target>/ (a missing or empty corpus fails it),
# then inputs mutated from them (bit flips, truncation, splices, garbage), fixed seed plus
# FUZZ_SEED if set, about 10 s per crate (ci/fuzz_replay.rs). It finds what is near the kept
# corpus; this script explores (coverage-guided) and grows the corpus. A failure there writes
# the input to target/fuzz-failures/<target>/, which `cargo fuzz run <target> <file>` replays.
# Inputs this script finds (fuzz/artifacts/<target>/) and adds to the corpus (SHA-1 names) are
# git-ignored: the test replays them on this machine only. Once a crash is fixed, copy its
# input into fuzz/corpus/<target>/ under a name that says what it is, and commit it: CI then
# replays it on every run.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${FUZZ_SECONDS:-20}

if ! rustup toolchain list | grep -q '^nightly'; then
    echo "fuzz: installing the nightly toolchain (sanitizers need it)"
    rustup toolchain install nightly --profile minimal
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
    echo "fuzz: cargo install cargo-fuzz"
    cargo +nightly install --locked cargo-fuzz
fi

failed=()
for crate in firmware/mavlora/fuzz firmware/multirx/core/fuzz harness/fuzz; do
    dir=${crate%/fuzz}
    for target in $(cd "$dir" && cargo +nightly fuzz list); do
        mkdir -p "$crate/corpus/$target"
        printf '\n=== fuzz %s %s (%d s)\n' "$dir" "$target" "$seconds"
        log=$(mktemp)
        status=0
        (cd "$dir" && cargo +nightly fuzz run -O "$target" "fuzz/corpus/$target" -- \
            -max_total_time="$seconds" -print_final_stats=1) >"$log" 2>&1 || status=$?
        grep -E '^(Done|stat::number_of_executed_units|==[0-9]+==ERROR|thread .* panicked|SUMMARY)' "$log" || true
        if [ "$status" != 0 ]; then
            tail -n 30 "$log"
            failed+=("$dir:$target")
        fi
        rm -f "$log"
    done
done
if [ ${#failed[@]} -gt 0 ]; then
    echo "fuzz: FAILED: ${failed[*]}" >&2
    exit 1
fi
echo "fuzz: every target ran ${seconds} s without a failure"
