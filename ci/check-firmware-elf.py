#!/usr/bin/env python3
"""Hardware-free checks of the MultiRX SAMD21 image (ARMv6-M / Thumb), from the ELF alone:

1. no panic path is reachable from the UART interrupts (SERCOM0..5): a panic in
   an RX handler resets the board (panic-reset) and the flight controller
   loses SBUS, so the handlers must not be able to panic at all;
2. a stack-use bound: the deepest call chain from `main`, plus the deepest
   from any interrupt handler (they share one priority, so they do not nest)
   plus the 32-byte exception frame, must fit the RAM the stack has (RAM
   minus static data);
3. a bound on the time cortex-m-rt's reset handler spends zeroing `.bss` and
   copying `.data` before `main`, at the reset clock: that time comes before
   the timer the boot line's `first-frame-us` counts from, so it is what the
   figure leaves out (see MEMORY_INIT_LIMIT_US for the limit and where it
   comes from). The loops are read from the ELF's `Reset` and priced
   instruction by instruction; a loop of any other shape fails the check.

How: a call graph from the symbol table and the code itself (32-bit BL,
16-bit B tail calls to another function's start), frame sizes from each
function's prologue (PUSH, SUB SP, and LDR Rn,=imm + ADD SP,Rn for big
frames), the approach of cargo-call-stack, which needs a nightly toolchain
(-Z emit-stack-sizes) this repository does not pin. Limits, said on the
output: an indirect call (BLX Rn) or recursion makes the bound unknown and
fails the interrupt check; elsewhere it may reach any function whose
address is taken (conservative); recursion other than core::fmt::write's
(one level per nested Display, counted FMT_NESTING deep) fails the check; literal pools decoded as code could only add edges (never
hide one), so errors err on the side of failing.

Usage: check-firmware-elf.py ELF [--ram-bytes N] [--ram-static N]
Exit codes: 0 checks pass; 1 a check failed; 2 bad input.
"""
import argparse
import struct
import sys

STT_FUNC = 2
SHT_SYMTAB = 2
EXCEPTION_FRAME = 32  # r0-r3, r12, lr, pc, xpsr (plus up to 4 for alignment, below)
ROOT_IRQS = [f"SERCOM{i}" for i in range(6)]
# core::fmt re-enters itself once per nested Display (fmt::write -> Display::fmt
# -> write! -> fmt::write): a status line is TimedEvent/BootReport -> Event ->
# LinkState or an integer, 3 deep; re-entries are counted 4 deep. With the
# conservative indirect targets the graph also shows cycles the code cannot
# take (Formatter::pad -> any Display::fmt); they are unrolled the same way.
# Recursion outside core::fmt fails the check.
FMT_NESTING = 4

# 3. Reset-handler RAM initialisation.
# The SAM D21 leaves reset on OSC8M with its reset prescaler /8: 1 MHz (datasheet
# DS40001882, SYSCTRL OSC8M.PRESC reset value 0x3), with NVMCTRL.CTRLB.RWS = 0 (no
# flash wait states); `clocks::start` raises it only after the reset handler ran.
RESET_CLOCK_HZ = 1_000_000
# The bench step that reads `first-frame-us` ("First power-on on the bench", item
# 1, in firmware/multirx/samd21/README.md) wants it to agree with a scope's
# reset-to-first-frame within 1 ms: everything before the timer starts must stay
# under 1 ms. Half of it is left for the register set-up before the timer (the
# watchdog's two synchronisations, <= 2 x 186 us at 32,768 Hz, then the brown-out
# detector and the clocks); the other half is the RAM initialisation's.
BENCH_AGREEMENT_US = 1000
MEMORY_INIT_LIMIT_US = BENCH_AGREEMENT_US // 2


# Every defined symbol's value (linker-script symbols such as __sbss included).
SYMBOLS = {}


def load(path):
    data = open(path, "rb").read()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        sys.exit(f"{path}: not a little-endian ELF32 file")
    shoff = struct.unpack_from("<I", data, 0x20)[0]
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
    sections = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    funcs, names = {}, {}
    for s in sections:
        if s[1] != SHT_SYMTAB:
            continue
        strtab = sections[s[6]]
        for off in range(s[4], s[4] + s[5], 16):
            name_off, value, size, info, _other, shndx = struct.unpack_from("<IIIBBH", data, off)
            end = data.index(b"\0", strtab[4] + name_off)
            name = data[strtab[4] + name_off:end].decode(errors="replace")
            if shndx != 0:
                SYMBOLS.setdefault(name, value)
            if info & 0xF != STT_FUNC or size == 0 or shndx == 0:
                continue
            funcs.setdefault(value & ~1, (name, size))
            names[name] = value & ~1
    # Code bytes by address, from the sections that hold them; every other
    # loaded word that is a Thumb function address (bit 0 set) is a function
    # whose address is taken (vtables, function pointers): what an indirect
    # call may reach.
    shstr = sections[shstrndx]

    def section_name(s):
        end = data.index(b"\0", shstr[4] + s[0])
        return data[shstr[4] + s[0]:end].decode()

    code, words = [], set()
    for s in sections:
        (_n, kind, flags, addr, offset, size, *_r) = s
        if not flags & 0x2 or kind == 8:  # SHF_ALLOC, not NOBITS
            continue
        blob = data[offset:offset + size]
        if flags & 0x4:  # SHF_EXECINSTR
            code.append((addr, blob))
        if section_name(s) == ".vector_table":
            continue  # handlers are entered by exceptions, not by calls
        words.update(struct.unpack_from("<I", blob, i)[0] for i in range(0, len(blob) - 3, 4))
    taken = {w & ~1 for w in words if w & 1 and (w & ~1) in funcs}
    return funcs, names, code, taken


def reader(code):
    def half(addr):
        for base, blob in code:
            if base <= addr < base + len(blob) - 1:
                return struct.unpack_from("<H", blob, addr - base)[0]
        return None

    def word(addr):
        lo, hi = half(addr), half(addr + 2)
        return None if lo is None or hi is None else lo | hi << 16

    return half, word


def analyse(addr, size, starts, half, word):
    """Callees, frame bytes and indirect-call flag of one function."""
    callees, frame, indirect = set(), 0, False
    pc, end, n = addr, addr + size, 0
    pending_ldr = {}
    while pc < end:
        hw = half(pc)
        if hw is None:
            break
        n += 1
        if hw >> 11 in (0b11101, 0b11110, 0b11111):  # 32-bit instruction
            hw2 = half(pc + 2) or 0
            if hw >> 11 == 0b11110 and hw2 & 0xD000 == 0xD000:  # BL
                s = hw >> 10 & 1
                i1 = ~((hw2 >> 13 & 1) ^ s) & 1
                i2 = ~((hw2 >> 11 & 1) ^ s) & 1
                imm = s << 24 | i1 << 23 | i2 << 22 | (hw & 0x3FF) << 12 | (hw2 & 0x7FF) << 1
                if s:
                    imm -= 1 << 25
                target = pc + 4 + imm
                if target in starts:
                    callees.add(target)
            pc += 4
            continue
        if hw & 0xF800 == 0xE000:  # B (unconditional): a tail call if it leaves
            imm = (hw & 0x7FF) << 1
            if imm & 0x800:
                imm -= 0x1000
            target = pc + 4 + imm
            if target in starts and not addr <= target < end:
                callees.add(target)
        elif hw & 0xFF87 == 0x4780:  # BLX Rm
            indirect = True
        if n <= 16:  # prologue
            if hw & 0xFE00 == 0xB400:  # PUSH {regs[, lr]}
                frame += 4 * (bin(hw & 0xFF).count("1") + (hw >> 8 & 1))
            elif hw & 0xFF80 == 0xB080:  # SUB SP, #imm7*4
                frame += 4 * (hw & 0x7F)
            elif hw & 0xF800 == 0x4800:  # LDR Rd, [PC, #imm8*4]
                lit = word(((pc + 4) & ~3) + 4 * (hw & 0xFF))
                if lit is not None:
                    pending_ldr[hw >> 8 & 7] = lit
            elif hw & 0xFF87 == 0x4485:  # ADD SP, Rm
                rm = hw >> 3 & 0xF
                lit = pending_ldr.get(rm)
                if lit is not None and lit & 0x8000_0000:
                    frame += (1 << 32) - lit
        pc += 2
    return callees, frame, indirect


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("elf")
    ap.add_argument("--ram-bytes", type=int, default=32 * 1024, help="RAM of the chip")
    ap.add_argument("--ram-static", type=int, default=0, help="static RAM the image uses")
    args = ap.parse_args()
    funcs, by_name, code, taken = load(args.elf)
    if not funcs:
        print(f"{args.elf}: no function symbols (stripped?)", file=sys.stderr)
        return 2
    half, word = reader(code)
    starts = set(funcs)
    info = {a: analyse(a, size, starts, half, word) for a, (_name, size) in funcs.items()}
    # An indirect call may reach any function whose address is taken.
    info = {a: (callees | taken if ind else callees, frame, ind) for a, (callees, frame, ind) in info.items()}
    name = lambda a: funcs[a][0]
    failed = False

    # 1. Panics reachable from the UART interrupts.
    def path_to_panic(root):
        seen, stack = {root: None}, [root]
        while stack:
            a = stack.pop()
            if "panic" in name(a) or "unwrap_failed" in name(a) or "expect_failed" in name(a):
                chain = []
                while a is not None:
                    chain.append(name(a))
                    a = seen[a]
                return list(reversed(chain))
            for c in info[a][0]:
                if c not in seen:
                    seen[c] = a
                    stack.append(c)
        return None

    irqs = [by_name[n] for n in ROOT_IRQS if n in by_name]
    if len(irqs) != len(ROOT_IRQS):
        missing = [n for n in ROOT_IRQS if n not in by_name]
        print(f"FAIL: interrupt handlers not found in the symbol table: {missing}")
        return 1
    for irq in irqs:
        chain = path_to_panic(irq)
        if chain:
            print(f"FAIL: a panic is reachable from {name(irq)}: {' -> '.join(chain)}")
            failed = True
        if any(info[a][2] for a in reachable(irq, info)):
            print(f"FAIL: {name(irq)} reaches an indirect call: its panic freedom and stack use are unknown")
            failed = True
    if not failed:
        print(f"ok: no panic path from {', '.join(ROOT_IRQS)}")

    # 2. Stack bound.
    memo = {}

    def in_fmt(a):
        n = name(a)
        return "core3fmt" in n or "core..fmt" in n or "_ZN4core3fmt" in n

    def depth(a, on_path, nesting):
        """Deepest stack from `a`; `nesting`: core::fmt re-entries on the path."""
        if a in on_path:
            if not in_fmt(a):
                raise RecursionError(" -> ".join(name(x) for x in on_path + [a]))
            nesting += 1
            if nesting > FMT_NESTING:
                return (0, [])  # cut: this re-entry was counted FMT_NESTING times
        key = (a, nesting, a in on_path)
        if key in memo and a not in on_path:
            return memo[key]
        callees, frame, _indirect = info[a]
        best = max((depth(c, on_path + [a], nesting) for c in callees), default=(0, []))
        result = (frame + best[0], [f"{name(a)} ({frame} B)"] + best[1])
        if a not in on_path:
            memo[key] = result
        return result

    entry = by_name.get("main")
    if entry is None:
        print("FAIL: no `main` symbol")
        return 1
    try:
        main_use, main_chain = depth(entry, [], 0)
        irq_use, irq_chain = max((depth(i, [], 0) for i in irqs), key=lambda d: d[0])
    except RecursionError as e:
        print(f"FAIL: stack use unbounded: {e}")
        return 1
    total = main_use + irq_use + EXCEPTION_FRAME + 4
    room = args.ram_bytes - args.ram_static
    print(f"stack: main {main_use} B + deepest interrupt {irq_use} B + exception frame "
          f"{EXCEPTION_FRAME + 4} B = {total} B of {room} B free RAM")
    print(f"  deepest from main: {' -> '.join(main_chain[:8])}{' ...' if len(main_chain) > 8 else ''}")
    print(f"  deepest interrupt: {' -> '.join(irq_chain[:8])}")
    if total > room:
        print(f"FAIL: stack bound {total} B exceeds the {room} B left after static data")
        failed = True

    # 3. RAM initialisation before main.
    reset = by_name.get("Reset")
    if reset is None:
        print("FAIL: no `Reset` symbol (cortex-m-rt's reset handler)")
        return 1
    try:
        loops = memory_init_loops(reset, funcs[reset][1], half, word)
    except ValueError as e:
        print(f"FAIL: cortex-m-rt's reset handler: {e}")
        return 1
    init_cycles = 0
    parts = []
    for kind, words, per_word, fixed in loops:
        init_cycles += words * per_word + fixed
        parts.append(f"{kind} {words * 4} B x {per_word} cycles/word")
    init_us = init_cycles * 1e6 / RESET_CLOCK_HZ
    print(f"reset: RAM initialisation {init_cycles} cycles = {init_us:.0f} us at the "
          f"{RESET_CLOCK_HZ / 1e6:g} MHz reset clock ({'; '.join(parts)}); "
          f"limit {MEMORY_INIT_LIMIT_US} us")
    if init_us > MEMORY_INIT_LIMIT_US:
        print(f"FAIL: the reset handler's RAM initialisation takes {init_us:.0f} us, over "
              f"{MEMORY_INIT_LIMIT_US} us (half the bench's {BENCH_AGREEMENT_US} us between "
              f"first-frame-us and a scope): move large statics to `.uninit` and "
              f"initialise them after the clocks are up")
        failed = True
    return 1 if failed else 0


# Cortex-M0+ cycle counts (Cortex-M0+ Technical Reference Manual, ARM DDI 0484,
# 3.3 "Instruction set summary", Table 3-1), with no wait states: CMP and MOVS 1;
# a conditional branch 1 not taken, 2 taken; B 2; LDR 2; LDM/STM 1 + N registers.
def memory_init_loops(addr, size, half, word):
    """The word loops of the reset handler: (kind, words, cycles per word, fixed cycles).

    A loop is a backward B; its bounds are the literals the two registers its CMP
    compares were loaded with (LDR Rd, =imm) before it, its store base the start.
    """
    insns, pc = [], addr
    while pc < addr + size:
        hw = half(pc)
        if hw is None:
            raise ValueError(f"no code at {pc:#x}")
        if hw >> 11 in (0b11101, 0b11110, 0b11111):
            insns.append((pc, "bl32", hw))
            pc += 4
            continue
        insns.append((pc, None, hw))
        pc += 2
    regs, loops = {}, []
    for i, (pc, kind, hw) in enumerate(insns):
        if kind:
            continue
        if hw & 0xF800 == 0x4800:  # LDR Rd, [PC, #imm8*4]
            regs[hw >> 8 & 7] = word(((pc + 4) & ~3) + 4 * (hw & 0xFF))
        elif hw & 0xF800 == 0xE000:  # B
            imm = (hw & 0x7FF) << 1
            if imm & 0x800:
                imm -= 0x1000
            target = pc + 4 + imm
            if target >= pc:
                continue
            body = [(p, h) for p, k, h in insns if target <= p <= pc and not k]
            loops.append(price_loop(body, regs))
    if not loops:
        raise ValueError("no RAM initialisation loop found")
    return loops


def price_loop(body, regs):
    per_word, cmp_regs, base, loads = 0, None, None, False
    for pc, hw in body:
        if hw & 0xFFC0 == 0x4280:  # CMP Rn, Rm
            cmp_regs = (hw & 7, hw >> 3 & 7)
            per_word += 1
        elif hw & 0xF000 == 0xD000 and hw >> 8 & 0xF < 0xE:  # B<cond>, not taken
            per_word += 1
        elif hw & 0xF800 in (0xC000, 0xC800):  # STM / LDM Rn!, {regs}
            n = bin(hw & 0xFF).count("1")
            per_word += 1 + n
            if hw & 0x0800:
                loads = True
            else:
                base = hw >> 8 & 7
                if n != 1:
                    raise ValueError(f"STM of {n} registers at {pc:#x}: not a word loop")
        elif hw & 0xF800 == 0xE000:  # B back
            per_word += 2
        else:
            raise ValueError(f"instruction {hw:#06x} at {pc:#x} in a RAM loop: price it")
    if cmp_regs is None or base is None:
        raise ValueError("a loop without CMP and STM: not cortex-m-rt's")
    end_reg = cmp_regs[0] if cmp_regs[1] == base else cmp_regs[1]
    start, end = regs.get(base), regs.get(end_reg)
    if start is None or end is None or end < start:
        raise ValueError("a RAM loop whose bounds are not literals")
    # Leaving: the last CMP (1) and the taken branch (2); setting up: up to three
    # LDR (2 each) and a MOVS (1).
    fixed = 3 + 7
    kind = "copy .data" if loads else "zero .bss"
    bounds = ("__sdata", "__edata") if loads else ("__sbss", "__ebss")
    if all(b in SYMBOLS for b in bounds) and (start, end) != tuple(SYMBOLS[b] for b in bounds):
        raise ValueError(f"the {kind} loop runs {start:#x}..{end:#x}, not {bounds[0]}..{bounds[1]}")
    return (kind, (end - start) // 4, per_word, fixed)


def reachable(root, info):
    seen, stack = {root}, [root]
    while stack:
        for c in info[stack.pop()][0]:
            if c not in seen:
                seen.add(c)
                stack.append(c)
    return seen


if __name__ == "__main__":
    sys.exit(main())
