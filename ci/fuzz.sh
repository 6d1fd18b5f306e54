#!/usr/bin/env bash
# Runs every cargo-fuzz target of the three fuzz crates for FUZZ_SECONDS each (default 20),
# starting from the corpus kept in the repository. A crash, a failed invariant (assert) or a
# leak fails the script, naming the target; the input that did it is under the crate's
# fuzz/artifacts/<target>/.
#
# Needs the nightly toolchain (sanitizers) and cargo-fuzz: installs cargo-fuzz from crates.io
# if it is missing. Long runs: FUZZ_SECONDS=600 bash ci/fuzz.sh
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
