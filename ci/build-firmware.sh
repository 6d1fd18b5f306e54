#!/usr/bin/env bash
# Builds the MultiRX SAMD21 firmware in release for both memory layouts (bare
# chip, and behind the 8 KiB UF2 bootloader) and prints flash and RAM use of
# each, as a share of the ATSAMD21G18A (256 KiB flash, 32 KiB RAM). Also writes
# the UF2 layout as a .uf2 file for the bootloader's USB drive.
#
# Needs only cargo (with the thumbv6m-none-eabi target, which
# rust-toolchain.toml pulls in) and python3's standard library: sizes come from
# the ELF section headers, not from llvm-size or binutils.
#
# Usage: ci/build-firmware.sh [OUT_DIR]   (default: firmware/multirx/samd21/target/dist)
# Environment: MULTIRX_CONFIG (see firmware/multirx/samd21/README.md) is passed through;
# CARGO_TARGET_DIR is honoured.
# Then ci/check-firmware-elf.py: no panic reachable from the UART interrupts,
# a stack-use bound within the RAM the stack has, and the reset handler's RAM
# initialisation (zeroing .bss, copying .data at the 1 MHz reset clock) within
# its limit, printed in microseconds.
# Exit codes: 0 built, measured and checked; non-zero if a build, a measurement or a check failed.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
crate="$repo/firmware/multirx/samd21"
out="${1:-$crate/target/dist}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
# cargo puts the image under CARGO_TARGET_DIR when it is set (absolute, or relative to
# where this script was started), else in the crate's own target folder.
target_dir="${CARGO_TARGET_DIR:-$crate/target}"
[[ $target_dir == /* ]] || target_dir="$PWD/$target_dir"
export CARGO_TARGET_DIR="$target_dir"
elf="$target_dir/thumbv6m-none-eabi/release/multirx-samd21"

for layout in bare uf2; do
    features=()
    if [[ $layout == uf2 ]]; then
        features=(--features uf2)
    fi
    echo "== building $layout layout" >&2
    start=$SECONDS
    (cd "$crate" && cargo build --release --locked "${features[@]}")
    echo "== built $layout in $((SECONDS - start)) s" >&2
    cp "$elf" "$out/multirx-samd21-$layout.elf"
done

python3 - "$out" <<'PY'
"""Flash/RAM use from ELF32 section headers; UF2 image from program headers."""
import struct
import sys
from pathlib import Path

CHIP_FLASH = 256 * 1024
CHIP_RAM = 32 * 1024
# The image's budget (the project's, checked without hardware): far below the chip, so
# growth is noticed long before the part runs out, and the stack keeps >= 24 KiB.
FLASH_BUDGET = 32 * 1024
RAM_BUDGET = 8 * 1024
RAM_START = 0x2000_0000
SHF_ALLOC = 0x2
SHT_NOBITS = 8
PT_LOAD = 1

# UF2 (https://github.com/microsoft/uf2): 512-byte blocks of 256 payload bytes.
UF2_MAGIC = (0x0A324655, 0x9E5D5157, 0x0AB16F30)
UF2_FLAG_FAMILY = 0x0000_2000
UF2_FAMILY_SAMD21 = 0x68ED_2B88
UF2_PAYLOAD = 256


def elf32(data):
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        sys.exit("not a little-endian ELF32 file")
    (phoff, shoff) = struct.unpack_from("<II", data, 0x1C)
    (phentsize, phnum, shentsize, shnum, shstrndx) = struct.unpack_from("<HHHHH", data, 0x2A)
    sections = []
    for i in range(shnum):
        sections.append(struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize))
    strtab = sections[shstrndx][4]

    def name(off):
        end = data.index(b"\0", strtab + off)
        return data[strtab + off : end].decode()

    named = [(name(s[0]), s) for s in sections]
    segments = [struct.unpack_from("<IIIIIIII", data, phoff + i * phentsize) for i in range(phnum)]
    return named, segments


def measure(named):
    flash = ram = 0
    parts = []
    for name, (_, kind, flags, addr, _, size, *_rest) in named:
        if not flags & SHF_ALLOC or size == 0:
            continue
        in_ram = addr >= RAM_START
        loaded = kind != SHT_NOBITS
        if loaded:  # stored in flash (.data: its initial values)
            flash += size
        if in_ram:
            ram += size
        parts.append(f"{name} {size}")
    return flash, ram, parts


def uf2(segments, data):
    image = {}
    for (ptype, offset, _vaddr, paddr, filesz, *_rest) in segments:
        if ptype == PT_LOAD and filesz:
            for i in range(filesz):
                image[paddr + i] = data[offset + i]
    if not image:
        sys.exit("no loadable bytes")
    start = min(image) // UF2_PAYLOAD * UF2_PAYLOAD
    end = max(image) + 1
    blocks = list(range(start, end, UF2_PAYLOAD))
    out = bytearray()
    for n, addr in enumerate(blocks):
        payload = bytes(image.get(addr + i, 0xFF) for i in range(UF2_PAYLOAD))
        head = struct.pack(
            "<IIIIIIII", UF2_MAGIC[0], UF2_MAGIC[1], UF2_FLAG_FAMILY, addr,
            UF2_PAYLOAD, n, len(blocks), UF2_FAMILY_SAMD21,
        )
        out += head + payload.ljust(476, b"\0") + struct.pack("<I", UF2_MAGIC[2])
    return bytes(out), start


out = Path(sys.argv[1])
print(f"{'layout':<6} {'flash':>22} {'RAM':>22}  sections")
for layout, app_flash in (("bare", CHIP_FLASH), ("uf2", CHIP_FLASH - 8 * 1024)):
    data = (out / f"multirx-samd21-{layout}.elf").read_bytes()
    named, segments = elf32(data)
    flash, ram, parts = measure(named)
    if flash == 0:
        sys.exit(f"{layout}: no flash contents found")
    if flash > app_flash or ram > CHIP_RAM:
        sys.exit(f"{layout}: does not fit ({flash} B flash of {app_flash}, {ram} B RAM)")
    if flash > FLASH_BUDGET or ram > RAM_BUDGET:
        sys.exit(
            f"{layout}: over budget ({flash} B flash, limit {FLASH_BUDGET}; {ram} B RAM, limit {RAM_BUDGET})"
        )
    if not any(name == ".vector_table" for name, _ in named):
        sys.exit(f"{layout}: no .vector_table section: linked without cortex-m-rt's link.x")
    print(
        f"{layout:<6} {flash:>7} B {100 * flash / CHIP_FLASH:5.1f} % of 256K"
        f" {ram:>7} B {100 * ram / CHIP_RAM:5.1f} % of 32K  {', '.join(parts)}"
    )
    if layout == "uf2":
        image, base = uf2(segments, data)
        if base < 0x2000:
            sys.exit(f"uf2: image starts at {base:#x}, inside the bootloader")
        (out / "multirx-samd21.uf2").write_bytes(image)
print(f"budget: flash <= {FLASH_BUDGET} B, RAM <= {RAM_BUDGET} B (both layouts within it)")
print("RAM is static data (.data + .bss + .uninit); the stack takes the rest, from the top of RAM down.")
print(f"UF2 image for the bootloader drive: {out / 'multirx-samd21.uf2'}")
PY

# No panic path from the UART interrupts, a stack bound that fits the RAM
# left after the static-data budget (8 KiB, enforced above), and the time the
# reset handler spends on .bss and .data before the boot line's timer starts.
for layout in bare uf2; do
    echo "== checking $layout layout (panic paths, stack bound, reset RAM initialisation)" >&2
    python3 "$repo/ci/check-firmware-elf.py" "$out/multirx-samd21-$layout.elf" \
        --ram-bytes $((32 * 1024)) --ram-static $((8 * 1024))
done
