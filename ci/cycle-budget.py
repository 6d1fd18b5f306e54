#!/usr/bin/env python3
"""The MultiRX core's CPU budget on the SAMD21 (a 48 MHz Cortex-M0+), measured, and checked.

Builds the benchmark `firmware/multirx/cycles` (multirx-core for thumbv6m-none-eabi, the
firmware's release profile), runs it on QEMU's micro:bit machine (a Cortex-M0: the same
ARMv6-M instructions) with one instruction per translation block and an execution trace
(`-singlestep`, `-accel tcg,one-insn-per-tb=on` from QEMU 8.1; `-d exec,nochain`), so each
trace line is one executed instruction. The benchmark marks its regions by calling
`cycles_region_start` / `cycles_region_end` and names them on the semihosting console;
instructions between the markers are counted, minus the markers' own cost (the `empty`
region). Each executed instruction is decoded from the ELF and costed at the Cortex-M0+'s
documented timing (CYCLES below).

Prints per region the instructions and estimated cycles (mean and maximum over the
measured rounds), then the steady load of RECEIVERS receivers each sending a frame every
RECEIVER_PERIOD_MS plus the output frame and the boot line, as a share of 48 MHz.

Fails (exit 1) when the load exceeds --max-share-pct (default 15 %) or a received frame
needs more than --max-frame-insns (default 2,000) instructions: the project's
requirements (the MultiRX cycle budget), not measured values. The limits are checked
against the worst of the measured rounds, and the share against the estimate at the
TRM's timings (--wait-states 0, the requirement's definition) unless --wait-states 1
asks for the one that charges the flash wait state on every fetch (below).

Usage: ci/cycle-budget.py [--max-share-pct P] [--max-frame-insns N] [--wait-states 0|1]
                          [--keep-trace]
Environment: CYCLE_BUDGET_MAX_SHARE_PCT, CYCLE_BUDGET_MAX_FRAME_INSNS,
CYCLE_BUDGET_WAIT_STATES (the flags win); CARGO_TARGET_DIR is honoured.
Needs: cargo (the thumbv6m-none-eabi target, from rust-toolchain.toml), qemu-system-arm
(Debian package qemu-system-arm), python3's standard library.
Exit codes: 0 within budget; 1 over budget; 2 the benchmark could not be built, run or read.
"""
import argparse
import os
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CRATE = REPO / "firmware" / "multirx" / "cycles"
BINARY = "multirx-cycles"

# The requirement: six receivers sending every 7 ms (SBUS high speed), on a 48 MHz M0+.
RECEIVERS = 6
RECEIVER_PERIOD_MS = 7
CPU_HZ = 48_000_000
BOOT_LINES_PER_S = 1  # the firmware repeats the boot line every second
FRAME_REGIONS = ("frame_slice_active", "frame_slice_standby")

# Cortex-M0+ instruction timings, in cycles, with zero-wait-state memory: ARM Cortex-M0+
# Technical Reference Manual (ARM DDI 0484C), section 3.3, Table 3.1 "Cortex-M0+
# instruction summary". N is the number of registers in the list (PC not counted).
CYCLES = {
    "alu": 1,          # data processing, MOV, CMP, shifts, extends, REV, NOP, CPS
    "mul": 1,          # MULS: 1 with the fast multiplier, which the SAMD21 has
    "load_store": 2,   # LDR*/STR* of every addressing mode, PC-relative included
    "ldm_stm": 1,      # + N: LDM, STM
    "push": 1,         # + N
    "pop": 1,          # + N
    "pop_pc": 3,       # + N: POP with PC (a return); N counts the registers besides PC
    "b_cond_taken": 2,  # the M0+'s 2-stage pipeline refills
    "b_cond_not": 1,
    "b": 2,            # B (unconditional)
    "bl": 3,           # BL
    "bx_blx": 2,       # BX, BLX register
    "pc_write": 2,     # ADD PC, Rm / MOV PC, Rm
    "barrier": 3,      # DMB, DSB, ISB
    "mrs_msr": 3,      # MRS, MSR
    "wfi_wfe": 2,
    "bkpt_svc": 0,     # semihosting calls: outside every measured region
}
# Exception entry: the M0+'s documented 15-cycle interrupt latency (zero wait states,
# ARM Cortex-M0+ product specification / TRM). Return unstacks the same eight words: it
# is charged 15 cycles too (ARM gives no separate figure). Hardware, not instructions:
# added to each received byte's interrupt (the SERCOM holds two bytes, so at 100 kbaud
# the handler usually runs once per byte).
EXCEPTION_ENTRY_AND_RETURN = 15 + 15
# Flash: at 48 MHz the SAMD21's NVM needs one wait state (NVMCTRL RWS = 1, set by
# ../firmware/multirx/samd21/src/clocks.rs). The M0+ fetches 32 bits (two 16-bit
# instructions) at a time. The "1 WS" estimate charges one cycle for every fetch of a new
# word (a word not fetched just before, or any fetch after a branch) and one for every
# literal-pool load, i.e. as if the NVM read cache never hit; reads of other constant
# data in flash are not seen (the trace has no data addresses). The "0 WS" estimate is
# the TRM's timing alone (every fetch a cache hit).
FLASH_WAIT_STATES = 1

PT_LOAD = 1
SHT_SYMTAB = 2


def fail(message, code=2):
    print(f"cycle-budget: error: {message}", file=sys.stderr)
    sys.exit(code)


def read_elf(path):
    """The loadable bytes by address and the function symbols by name."""
    data = path.read_bytes()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        fail(f"{path}: not a little-endian ELF32 file")
    phoff, shoff = struct.unpack_from("<II", data, 0x1C)
    phentsize, phnum, shentsize, shnum = struct.unpack_from("<HHHH", data, 0x2A)
    segments = []
    for i in range(phnum):
        ptype, offset, _vaddr, paddr, filesz, *_ = struct.unpack_from("<IIIIIIII", data, phoff + i * phentsize)
        if ptype == PT_LOAD and filesz:
            segments.append((paddr, data[offset:offset + filesz]))
    sections = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    symbols = {}
    for s in sections:
        if s[1] != SHT_SYMTAB:
            continue
        strtab = sections[s[6]]
        for off in range(s[4], s[4] + s[5], 16):
            name_off, value, _size, _info, _other, _shndx = struct.unpack_from("<IIIBBH", data, off)
            end = data.index(b"\0", strtab[4] + name_off)
            symbols[data[strtab[4] + name_off:end].decode(errors="replace")] = value & ~1
    return segments, symbols


def halfword(segments, addr):
    for base, blob in segments:
        if base <= addr and addr + 2 <= base + len(blob):
            return struct.unpack_from("<H", blob, addr - base)[0]
    fail(f"executed address {addr:#x} is not in the image")


def classify(segments, pc):
    """(size in bytes, kind, extra N cycles, literal load) of the Thumb instruction at pc."""
    hw = halfword(segments, pc)
    top5 = hw >> 11
    if top5 in (0b11101, 0b11110, 0b11111):
        hw2 = halfword(segments, pc + 2)
        if top5 == 0b11110 and hw2 & 0xD000 == 0xD000:
            return 4, "bl", 0, False
        if hw & 0xFFF0 == 0xF3B0 and hw2 & 0xFF00 == 0x8F00:
            return 4, "barrier", 0, False
        if hw & 0xFFE0 in (0xF380, 0xF3E0):
            return 4, "mrs_msr", 0, False
        fail(f"unexpected 32-bit instruction {hw:#06x} {hw2:#06x} at {pc:#x}")
    if hw & 0xFFC0 == 0x4340:
        return 2, "mul", 0, False
    if hw & 0xFF00 == 0x4700:
        return 2, "bx_blx", 0, False
    if hw & 0xFC00 == 0x4400 and hw & 0x0300 in (0x0000, 0x0200):  # ADD / MOV high registers
        if (hw & 7) | ((hw >> 4) & 8) == 15:
            return 2, "pc_write", 0, False
        return 2, "alu", 0, False
    if hw & 0xF800 == 0x4800:
        return 2, "load_store", 0, True  # LDR Rt, [PC, #imm]: a literal pool in flash
    if hw & 0xF000 == 0x5000 or hw & 0xE000 == 0x6000 or hw & 0xF000 in (0x8000, 0x9000):
        return 2, "load_store", 0, False
    if hw & 0xFE00 == 0xB400:
        return 2, "push", bin(hw & 0x1FF).count("1"), False
    if hw & 0xFE00 == 0xBC00:
        regs = bin(hw & 0xFF).count("1")
        return 2, ("pop_pc" if hw & 0x100 else "pop"), regs, False
    if hw & 0xF000 == 0xC000:
        return 2, "ldm_stm", bin(hw & 0xFF).count("1"), False
    if hw & 0xFF00 == 0xBE00 or hw & 0xFF00 == 0xDF00:
        return 2, "bkpt_svc", 0, False
    if hw & 0xFFEF == 0xBF20:  # WFE (0xBF20), WFI (0xBF30)
        return 2, "wfi_wfe", 0, False
    if hw & 0xF000 == 0xD000:
        return 2, "b_cond", 0, False
    if hw & 0xF800 == 0xE000:
        return 2, "b", 0, False
    return 2, "alu", 0, False


def run_benchmark():
    target_dir = Path(os.environ.get("CARGO_TARGET_DIR", "target"))
    if not target_dir.is_absolute():
        target_dir = CRATE / target_dir
    print("cycle-budget: building firmware/multirx/cycles (thumbv6m-none-eabi, release)", flush=True)
    build = subprocess.run(["cargo", "build", "--release", "--locked"], cwd=CRATE)
    if build.returncode != 0:
        fail("building the benchmark failed (cargo's output above)")
    elf = target_dir / "thumbv6m-none-eabi" / "release" / BINARY
    if not elf.is_file():
        fail(f"{elf}: no benchmark image where cargo should have put it")
    qemu = "qemu-system-arm"
    try:
        version = subprocess.run([qemu, "--version"], capture_output=True, text=True).stdout
    except FileNotFoundError:
        fail(f"{qemu} not found: install Debian's qemu-system-arm (ci/setup.sh does)")
    # "QEMU emulator version 7.2.22 (...)": 8.1 renamed -singlestep (later removed).
    try:
        major, minor = (int(x) for x in version.split("version ", 1)[1].split(".")[:2])
    except (IndexError, ValueError):
        fail(f"cannot read {qemu}'s version from {version.strip()!r}")
    one_insn = (["-accel", "tcg,one-insn-per-tb=on"] if (major, minor) >= (8, 1)
                else ["-singlestep"])
    work = Path(tempfile.mkdtemp(prefix="cycle-budget-", dir=target_dir))
    trace, console = work / "trace.log", work / "console.log"
    command = [
        qemu, "-machine", "microbit", "-display", "none", "-serial", "none", "-monitor", "none",
        "-chardev", f"file,id=semihosting,path={console}",
        "-semihosting-config", "enable=on,target=native,chardev=semihosting",
        # One instruction per translation block, blocks never chained: one trace line per
        # executed instruction, with its address.
        *one_insn, "-d", "exec,nochain", "-D", str(trace),
        "-kernel", str(elf),
    ]
    print(f"cycle-budget: running {' '.join(command)}", flush=True)
    try:
        qemu_run = subprocess.run(command, timeout=300, stdin=subprocess.DEVNULL,
                                  capture_output=True, text=True)
    except FileNotFoundError:
        fail(f"{qemu} not found: install Debian's qemu-system-arm (ci/setup.sh does)")
    except subprocess.TimeoutExpired:
        fail(f"QEMU did not finish within 300 s (trace so far: {trace})")
    lines = console.read_text().splitlines() if console.exists() else []
    if qemu_run.returncode != 0 or "done" not in lines:
        fail(f"the benchmark did not run to its end (QEMU exit {qemu_run.returncode}); "
             f"its console: {lines[-3:]!r}; QEMU said: {qemu_run.stderr.strip()[-500:]!r}")
    return elf, trace, lines, work


def trace_pcs(trace):
    pcs = []
    with trace.open() as f:
        for line in f:
            if line.startswith("Trace "):
                # "Trace 0: 0x7f.. [flags/PC/flags/cflags] symbol"
                pcs.append(int(line.split("[", 1)[1].split("/", 2)[1], 16))
    if not pcs:
        fail(f"{trace}: no executed instructions in the trace")
    return pcs


def measure(segments, symbols, pcs, console):
    for name in ("cycles_region_start", "cycles_region_end"):
        if name not in symbols:
            fail(f"the benchmark image has no symbol {name}")
    start, end = symbols["cycles_region_start"], symbols["cycles_region_end"]
    names = []
    config = {}
    for line in console:
        words = line.split()
        if words[:1] == ["region"] and len(words) == 4 and words[2] == "per":
            names.append((words[1], int(words[3])))
        elif words[:1] == ["config"]:
            config = dict(zip(words[1::2], map(int, words[2::2])))
        elif words[:1] == ["error:"]:
            fail(f"the benchmark says: {line}")

    decoded = {}
    regions = []
    opened = None
    insns = cycles = waits = 0
    last_word = None
    for i, pc in enumerate(pcs):
        if pc == start:
            opened, insns, cycles, waits, last_word = i, 0, 0, 0, None
        elif pc == end and opened is not None:
            regions.append((insns, cycles, cycles + waits))
            opened = None
        if opened is None:
            continue
        if pc not in decoded:
            decoded[pc] = classify(segments, pc)
        size, kind, n, literal = decoded[pc]
        nxt = pcs[i + 1] if i + 1 < len(pcs) else None
        flow = nxt is not None and nxt != pc + size
        if kind == "b_cond":
            kind = "b_cond_taken" if flow else "b_cond_not"
        insns += 1
        cycles += CYCLES[kind] + n
        for word in {pc >> 2, (pc + size - 1) >> 2}:
            if word != last_word:
                waits += FLASH_WAIT_STATES
                last_word = word
        if literal:
            waits += FLASH_WAIT_STATES
        if flow:
            last_word = None  # the pipeline refetches from the branch target
    if len(regions) != len(names):
        fail(f"{len(names)} regions announced but {len(regions)} marked in the trace")
    if not names or names[0][0] != "empty":
        fail("the benchmark's first region must be `empty` (the markers' own cost)")
    base = regions[0]
    results = {}
    for (name, per), counts in zip(names[1:], regions[1:]):
        values = tuple((c - b) / per for c, b in zip(counts, base))
        results.setdefault(name, []).append(values)
    return config, results


def summary(samples):
    """Per column (instructions, cycles 0 WS, cycles 1 WS): mean and maximum."""
    columns = list(zip(*samples))
    return [(sum(c) / len(c), max(c)) for c in columns]


def main():
    sys.stdout.reconfigure(line_buffering=True)  # in order with cargo's and QEMU's output
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--max-share-pct", type=float,
                        default=float(os.environ.get("CYCLE_BUDGET_MAX_SHARE_PCT", 15)),
                        help="fail above this share of 48 MHz (default 15, the requirement)")
    parser.add_argument("--max-frame-insns", type=float,
                        default=float(os.environ.get("CYCLE_BUDGET_MAX_FRAME_INSNS", 2000)),
                        help="fail if a received frame needs more instructions (default 2000)")
    parser.add_argument("--wait-states", type=int, choices=(0, 1),
                        default=int(os.environ.get("CYCLE_BUDGET_WAIT_STATES", 0)),
                        help="check the share at 0 (TRM timings, default) or 1 flash wait state")
    parser.add_argument("--keep-trace", action="store_true", help="keep QEMU's trace and console")
    args = parser.parse_args()

    elf, trace, console, work = run_benchmark()
    segments, symbols = read_elf(elf)
    config, results = measure(segments, symbols, trace_pcs(trace), console)
    if args.keep_trace:
        print(f"cycle-budget: trace and console kept in {work}")
    else:
        trace.unlink()
        (work / "console.log").unlink(missing_ok=True)
        work.rmdir()

    missing = [r for r in (*FRAME_REGIONS, "output_period", "rx_interrupt", "rx_gather", "status_line", "boot_line")
               if r not in results]
    if missing:
        fail(f"the benchmark did not measure {', '.join(missing)}")
    if "output_period_us" not in config:
        fail("the benchmark did not print its configuration line")
    if config.get("receivers", 0) < RECEIVERS:
        fail(f"the benchmark's configuration has {config.get('receivers')} receivers, "
             f"the budget is for {RECEIVERS} (firmware/multirx/cycles/cycles.toml)")

    rounds = len(results[FRAME_REGIONS[0]])
    print(f"\nmultirx-core on thumbv6m (QEMU micro:bit), {rounds} measured rounds; "
          "cycles at the Cortex-M0+'s timings, 0 or 1 flash wait state")
    print(f"{'region (per unit)':<34} {'instructions':>16} {'cycles 0 WS':>16} {'cycles 1 WS':>16}")
    print(f"{'':<34} {'mean / max':>16} {'mean / max':>16} {'mean / max':>16}")
    stats = {}
    for name, samples in results.items():
        stats[name] = summary(samples)
        cols = "".join(f" {f'{mean:,.0f} / {peak:,.0f}':>16}" for mean, peak in stats[name])
        print(f"{name:<34}{cols}")
    print(f"(rx_interrupt excludes exception entry and return: + {EXCEPTION_ENTRY_AND_RETURN} cycles"
          " per interrupt, added below)")

    frames_per_s = RECEIVERS * 1000 / RECEIVER_PERIOD_MS
    outputs_per_s = 1_000_000 / config["output_period_us"]
    bytes_per_s = frames_per_s * 25

    def load(column):
        frame = max(stats[r][column][1] for r in FRAME_REGIONS)
        byte = (stats["rx_interrupt"][column][1] + stats["rx_gather"][column][1]
                + (EXCEPTION_ENTRY_AND_RETURN if column else 0))
        return (frames_per_s * frame + bytes_per_s * byte
                + outputs_per_s * stats["output_period"][column][1]
                + BOOT_LINES_PER_S * stats["boot_line"][column][1])

    share_0ws = 100 * load(1) / CPU_HZ
    share_1ws = 100 * load(2) / CPU_HZ
    frame_insns = max(stats[r][0][1] for r in FRAME_REGIONS)
    print(f"\nsteady load: {RECEIVERS} receivers x 1 frame / {RECEIVER_PERIOD_MS} ms "
          f"({frames_per_s:,.0f} frames/s, each fed as one 25-byte slice, {bytes_per_s:,.0f} "
          f"bytes/s through the RX interrupt), output every {config['output_period_us'] / 1000:g} ms, "
          f"boot line every second (worst round of each; status lines come with events only)")
    print(f"  instructions per received frame: {frame_insns:,.0f} (limit {args.max_frame_insns:,.0f})")
    share = share_1ws if args.wait_states else share_0ws
    print(f"  share of 48 MHz: {share_0ws:.1f} % at 0 WS (TRM timings), {share_1ws:.1f} % at 1 WS "
          f"(every flash fetch waits); limit {args.max_share_pct:g} %, checked at "
          f"{args.wait_states} WS")

    failures = []
    if frame_insns > args.max_frame_insns:
        failures.append(f"a received frame needs {frame_insns:,.0f} instructions, "
                        f"more than the limit of {args.max_frame_insns:,.0f}")
    if share > args.max_share_pct:
        failures.append(f"{RECEIVERS} receivers at {RECEIVER_PERIOD_MS} ms plus the output need "
                        f"{share:.1f} % of 48 MHz ({args.wait_states} flash wait states), more "
                        f"than the limit of {args.max_share_pct:g} %")
    for message in failures:
        print(f"cycle-budget: FAIL: {message}", file=sys.stderr)
    if failures:
        sys.exit(1)
    print("cycle-budget: within budget")


if __name__ == "__main__":
    main()
