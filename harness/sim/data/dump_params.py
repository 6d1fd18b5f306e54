"""Dumps a real autopilot's whole parameter list, as its serial MAVLink port sends it, into
the table the simulated autopilots of `harness-sim` stream (`src/autopilot/params.rs`).

    python3 dump_params.py ardupilot ../../../../shared/ardupilot-sitl > ardupilot-copter-4.6.3.tsv
    python3 dump_params.py px4 ../../../../shared/px4-sitl > px4-1.16.0-sih.tsv

The SITL runs in a temporary working folder with its telemetry port on a pty pair (ArduPilot's
SERIAL1, PX4's `PX4_MAVLINK_SERIAL`, both at 57600 baud), where the bridge would read it. The
script asks for the list (PARAM_REQUEST_LIST), takes every PARAM_VALUE as it arrives, then
reads what is missing by index; it writes one line per parameter: index, name, type
(MAV_PARAM_TYPE) and the value's four payload bytes as eight hexadecimal digits (little
endian, exactly as sent: PX4's integers byte-wise, ArduPilot's as floats), after comment
lines saying what was measured (how long the first pass took on the serial port).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
import tty

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402


def start(kind: str, root: str, slave: str, work: str) -> subprocess.Popen:
    root = os.path.abspath(root)
    if kind == "ardupilot":
        cmd = [os.path.join(root, "arducopter"), "-w", "--model", "quad", "--speedup", "1",
               "--defaults", os.path.join(root, "copter.parm"),
               "--home", "-35.363261,149.165230,584,353", "-I13",
               "--serial0", "tcp:0", "--serial1", f"uart:{slave}:57600"]
        env = os.environ.copy()
    else:
        # PX4's start-up script runs its client commands (links to `px4`, `px4-param`...)
        # from PATH; links may not survive a copy, so they are made afresh, as the rig does.
        program = os.path.join(root, "bin", "px4")
        bin_dir = os.path.join(work, "bin")
        os.makedirs(bin_dir)
        for name in os.listdir(os.path.join(root, "bin")):
            if name == "px4-alias.sh":
                os.symlink(os.path.join(root, "bin", name), os.path.join(bin_dir, name))
            elif name.startswith("px4-"):
                os.symlink(program, os.path.join(bin_dir, name))
        cmd = [program, "-d", os.path.join(root, "etc"), "-w", work, "-i", "7"]
        env = dict(os.environ, PATH=bin_dir + ":" + os.environ["PATH"],
                   PX4_SIM_MODEL="sihsim_quadx", PX4_SIMULATOR="sihsim",
                   PX4_MAVLINK_SERIAL=slave, PX4_MAVLINK_BAUD="57600")
    return subprocess.Popen(cmd, cwd=work, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


def payload(m) -> bytes:
    """A message's payload as received, zero-padded to PARAM_VALUE's 25 bytes (pymavlink's
    own `get_payload` cuts a MAVLink 2 frame's at the wrong offset)."""
    buf = bytes(m.get_msgbuf())
    start = 10 if buf[0] == 0xFD else 6
    return buf[start:start + buf[1]].ljust(25, b"\0")


def main() -> int:
    kind, root = sys.argv[1], sys.argv[2]
    master, slave_fd = os.openpty()
    tty.setraw(slave_fd)
    tty.setraw(master)
    slave = os.ttyname(slave_fd)
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.robust_parsing = True
    work = tempfile.mkdtemp(prefix=f"dump-{kind}-")
    proc = start(kind, root, slave, work)
    values: dict[int, tuple[bytes, int, bytes]] = {}
    total = None
    first_pass: list[float] = []
    try:
        def send(msg) -> None:
            os.write(master, msg.pack(mav))

        def pump(seconds: float) -> list:
            out, end = [], time.monotonic() + seconds
            while time.monotonic() < end:
                import select
                r, _, _ = select.select([master], [], [], 0.05)
                if r:
                    out += [(time.monotonic(), m) for m in mav.parse_buffer(os.read(master, 4096)) or []]
            return out

        target = None
        deadline = time.monotonic() + 60
        while target is None and time.monotonic() < deadline:
            send(mav.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0))
            for _, m in pump(1.0):
                if m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1 \
                        and m.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
                    target = m.get_srcSystem()
        if target is None:
            raise SystemExit("no heartbeat")
        time.sleep(3)  # let the boot settle, as a ground station connecting later would
        pump(0.5)
        t0 = time.monotonic()
        send(mav.param_request_list_encode(target, 1))
        quiet_since = time.monotonic()
        hb = 0.0
        while True:
            if time.monotonic() - hb >= 1:
                hb = time.monotonic()
                send(mav.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0))
            got = pump(0.1)
            for t, m in got:
                if m.get_type() != "PARAM_VALUE" or m.get_srcComponent() != 1:
                    continue
                p = payload(m)
                total = m.param_count
                if m.param_index < m.param_count and m.param_index not in values:
                    values[m.param_index] = (p[8:24], p[24], p[0:4])
                    first_pass.append(t)
                    quiet_since = t
            if total is not None and len(values) >= total:
                break
            if time.monotonic() - quiet_since > 2:
                break
        listed = len(values)
        while total is not None and len(values) < total:
            missing = [i for i in range(total) if i not in values][:10]
            for i in missing:
                send(mav.param_request_read_encode(target, 1, b"", i))
            for _, m in pump(0.5):
                if m.get_type() == "PARAM_VALUE" and m.get_srcComponent() == 1 \
                        and m.param_index < m.param_count:
                    p = payload(m)
                    values.setdefault(m.param_index, (p[8:24], p[24], p[0:4]))
    finally:
        os.killpg(proc.pid, 15)
        proc.wait(10)
    span = first_pass[-1] - t0 if first_pass else 0.0
    print(f"# {kind} SITL ({root.rstrip('/').split('/')[-1]}), its serial MAVLink port on a pty at 57600 baud")
    print(f"# {total} parameters; the first pass of PARAM_REQUEST_LIST brought {listed} in {span:.2f} s")
    print("# index\tname\ttype\tvalue bytes (little endian, as sent)")
    for i in sorted(values):
        name, ptype, value = values[i]
        text = name.rstrip(b"\0").decode("ascii")
        assert "\t" not in text and "\0" not in text, text
        print(f"{i}\t{text}\t{ptype}\t{value.hex()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
