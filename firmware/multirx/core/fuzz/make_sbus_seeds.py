#!/usr/bin/env python3
"""Writes the seed inputs of the `sbus_stream` fuzz target to corpus/sbus_stream/.

The target reads its input twice: as one raw SBUS byte stream (the decoder), then as chunks
for the multiplexer: a header byte (receiver = head % 4, length = head & 31, time step =
(head >> 2) * 250 us) followed by that many bytes. The seeds carry valid frames both ways,
so mutations start next to the code paths that matter (acquire, forward, loss, scan).
Run from anywhere: python3 firmware/multirx/core/fuzz/make_sbus_seeds.py
"""
from pathlib import Path

OUT = Path(__file__).resolve().parent / "corpus" / "sbus_stream"


def frame(channels, ch17=False, ch18=False, lost=False, failsafe=False, footer=0x00):
    assert len(channels) == 16
    packed = sum((c & 0x7FF) << (11 * i) for i, c in enumerate(channels))
    flags = ch17 | ch18 << 1 | lost << 2 | failsafe << 3
    return bytes([0x0F]) + packed.to_bytes(22, "little") + bytes([flags, footer])


# The core's own test vector (src/wire/sbus.rs), packed independently here.
assert frame(
    [172, 992, 1811, 0, 2047, 1000, 1500, 1, 2, 4, 8, 16, 32, 64, 128, 1024],
    ch17=True, failsafe=True,
) == bytes.fromhex("0fac00dfc401f07ff4713700022000022000022000028009" "00")

NEUTRAL = [992] * 16
PILOT = [992, 1200, 300, 1700] + [992] * 12


def chunks(receiver, data, lengths, slow=0):
    """Chunk records for `receiver`: each length must be = receiver (mod 4)."""
    out, pos = bytearray(), 0
    for n in lengths:
        assert n % 4 == receiver and n < 32
        out += bytes([n | slow << 5]) + data[pos:pos + n]
        pos += n
    assert pos == len(data)
    return bytes(out)


def silence(ms):
    # Receiver 0, no bytes, 14 ms per record (head 0xE0 >> 2 = 56 steps of 250 us).
    return bytes([0xE0]) * (ms // 14)


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    raw = b"".join([
        frame(NEUTRAL), frame(PILOT), frame(PILOT, ch17=True), frame(PILOT, lost=True),
        frame(PILOT, footer=0x14), frame([172] * 16), frame([1811] * 16),
        frame(NEUTRAL, failsafe=True), frame(NEUTRAL, lost=True, failsafe=True),
    ])
    (OUT / "frames-raw").write_bytes(raw)

    # Scan mode (first byte odd): receiver 1 flies for 40 frames at ~7.5 ms, goes silent
    # for 2.5 s (scan cycles), then receiver 2 gets a link.
    scan = b"".join(chunks(1, frame(PILOT), [25], slow=3) for _ in range(40))
    scan += silence(2500)
    scan += b"".join(chunks(2, frame(PILOT) * 2, [30, 14, 6], slow=3) for _ in range(20))
    (OUT / "scan-handover").write_bytes(scan)

    # Parallel mode (first byte even): receivers 0 and 2 both fly, then receiver 0 reports
    # failsafe and receiver 2 carries on.
    par = bytearray()
    for _ in range(10):
        par += chunks(0, frame(PILOT) * 4, [28, 28, 28, 16], slow=1)
        par += chunks(2, frame(NEUTRAL) * 2, [30, 14, 6], slow=1)
    for _ in range(10):
        par += chunks(0, frame(NEUTRAL, failsafe=True) * 4, [28, 28, 28, 16], slow=1)
        par += chunks(2, frame(PILOT) * 2, [30, 14, 6], slow=1)
    (OUT / "parallel-failsafe").write_bytes(bytes(par))


if __name__ == "__main__":
    main()
