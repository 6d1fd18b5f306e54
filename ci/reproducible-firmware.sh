#!/usr/bin/env bash
# Two `rig build --firmware-only` runs in separate target folders, from two checkouts at
# different paths, must give byte-identical firmware images (same source + toolchain → same
# bytes). Prints both digests.
# Exit codes: 0 identical; 1 they differ; other: a build failed.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
cargo build --release --locked -p harness --bin rig
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The second build from a copy of the tree elsewhere (committed files only), so the
# checkout's absolute path is exercised too.
git worktree add --detach -q "$work/copy" HEAD
trap 'git -C "$repo" worktree remove --force "$work/copy"; rm -rf "$work"' EXIT
"$repo/target/release/rig" build --firmware-only --out "$work/a" --target-dir "$work/target-a"
(cd "$work/copy" && "$repo/target/release/rig" build --firmware-only --out "$work/b" --target-dir "$work/target-b")
a=$(sha256sum "$work"/a/artifacts/*.elf | cut -d' ' -f1)
b=$(sha256sum "$work"/b/artifacts/*.elf | cut -d' ' -f1)
echo "build 1: $a"
echo "build 2: $b"
if [ "$a" != "$b" ]; then
    echo "reproducible-firmware: the two builds differ" >&2
    exit 1
fi
echo "reproducible-firmware: identical"
