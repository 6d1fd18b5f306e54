"""Mission peers for ``tests/e2e_mission_peers.rs``: a pymavlink autopilot on a pty (the
bridge's ``--fc``) and pymavlink ground stations on the router's UDP port, playing one
scenario of issue 22's "Plans" against the real ``mavlora-bridge`` and ``mavlora-router``.

The autopilot answers the mission protocol as ArduPilot 4.6 (``opaque_id`` always 0, a
second upload from the same partner restarts, partial writes) or PX4 1.16 (``opaque_id``
set, the cleared plan named in a clear-all's ack, a second count mid-upload refused with an
error), over MAVLink 2 or MAVLink 1, storing a plan in ``--store-delay`` seconds (its link
is busy meanwhile, as a flash write blocks it). The ground stations upload as the spec says
(resend the last item on a timeout) or as MAVSDK does (each repeated request is a retry,
nothing resent while waiting for the ack).

Prints ``{"port": PTY}`` when ready, ``{"event": "restart-router"}`` when the scenario wants
the router restarted (then waits for a line on stdin), and last a JSON summary:
``{"checks": {name: [ok, detail]}, "ok": bool}``. Exit status 0 whatever the checks say.
"""

from __future__ import annotations

import argparse
import json
import os
import pty
import struct
import select
import sys
import time
import tty

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import common as mav  # noqa: E402

MISSION = mav.MAV_MISSION_TYPE_MISSION
FENCE = mav.MAV_MISSION_TYPE_FENCE
ACCEPTED = mav.MAV_MISSION_ACCEPTED
VEHICLE = (1, 1)
GCS = (255, 190)
MAVSDK = (245, 190)


def emit(obj) -> None:
    print(json.dumps(obj), flush=True)


def plan(n: int, salt: int, mtype: int = MISSION) -> list[dict]:
    return [dict(seq=s, frame=mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, command=mav.MAV_CMD_NAV_WAYPOINT,
                 x=553_700_000 + 1000 * s + salt, y=103_000_000 + salt, z=50.0, mission_type=mtype)
            for s in range(n)]


def same(a: list[dict], b: list[dict]) -> bool:
    key = ("seq", "frame", "command", "x", "y")
    return len(a) == len(b) and all(all(x[k] == y[k] for k in key) and abs(x["z"] - y["z"]) < 1e-3
                                    for x, y in zip(a, b))


def item_of(msg) -> dict:
    return dict(seq=msg.seq, frame=msg.frame, command=msg.command, x=msg.x, y=msg.y, z=msg.z,
                mission_type=getattr(msg, "mission_type", 0))


class Autopilot:
    """The autopilot on the pty: one plan per type, stored at the end of an upload."""

    def __init__(self, kind: str, mavlink1: bool, store_delay: float):
        self.kind, self.v1, self.store_delay = kind, mavlink1, store_delay
        master, slave = pty.openpty()
        tty.setraw(slave)
        self.fd, self.slave, self.port = master, slave, os.ttyname(slave)
        os.set_blocking(master, False)
        self.mav = mav.MAVLink(None, srcSystem=VEHICLE[0], srcComponent=VEHICLE[1])
        self.rx = mav.MAVLink(None)
        self.rx.robust_parsing = True
        self.plans: dict[int, list[dict]] = {MISSION: [], FENCE: []}
        self.upload = None  # dict(peer, type, first, last, items, next, asked, partial)
        self.storing = None  # (due, upload)
        self.backlog = []
        self.counts = 0  # MISSION_COUNTs received
        self.clears = 0
        self.accepted = []  # (type, plan) acked ACCEPTED after every item
        self.next_hb = 0.0

    def send(self, msg) -> None:
        data = msg.pack(self.mav, force_mavlink1=self.v1)
        self.mav.seq = (self.mav.seq + 1) % 256
        try:
            os.write(self.fd, data)
        except OSError:
            pass

    def ack(self, to, mtype: int, result: int, opaque: int = 0) -> None:
        if not opaque:
            self.send(mav.MAVLink_mission_ack_message(to[0], to[1], result, mtype))
            return
        # pymavlink 2.4's common.xml predates MISSION_ACK.opaque_id (an extension: the
        # checksum's CRC_EXTRA is the same): the frame is built here, as PX4 sends it.
        payload = struct.pack("<BBBBI", to[0], to[1], result, mtype, opaque)
        header = struct.pack("<BBBBBB", len(payload), 0, 0, self.mav.seq, VEHICLE[0], VEHICLE[1]) \
            + struct.pack("<I", mav.MAVLINK_MSG_ID_MISSION_ACK)[:3]
        crc = mav.x25crc(header + payload)
        crc.accumulate(bytes([mav.MAVLink_mission_ack_message.crc_extra]))
        self.mav.seq = (self.mav.seq + 1) % 256
        try:
            os.write(self.fd, b"\xfd" + header + payload + struct.pack("<H", crc.crc))
        except OSError:
            pass

    def request(self, to, mtype: int, seq: int) -> None:
        self.send(mav.MAVLink_mission_request_int_message(to[0], to[1], seq, mtype))

    def read(self, now: float) -> None:
        try:
            data = os.read(self.fd, 4096)
        except (BlockingIOError, OSError):
            return
        for msg in self.rx.parse_buffer(data) or []:
            if self.storing:
                self.backlog.append(msg)
            else:
                self.handle(msg, now)

    def handle(self, msg, now: float) -> None:
        t = msg.get_type()
        frm = (msg.get_srcSystem(), msg.get_srcComponent())
        mtype = getattr(msg, "mission_type", 0)
        if getattr(msg, "target_system", VEHICLE[0]) != VEHICLE[0]:
            return
        if t == "MISSION_COUNT":
            self.counts += 1
            up = self.upload
            if up and (up["peer"] != frm or self.kind == "px4"):
                if self.kind == "px4" and up["peer"] == frm and up["next"] == 0:
                    self.request(frm, up["type"], 0)
                    return
                self.ack(frm, mtype, mav.MAV_MISSION_DENIED if self.kind == "ardupilot" else mav.MAV_MISSION_ERROR)
                return
            if msg.count == 0:
                self.upload = None
                self.plans[mtype] = []
                self.accepted.append((mtype, []))
                self.ack(frm, mtype, ACCEPTED)
                return
            self.upload = dict(peer=frm, type=mtype, first=0, last=msg.count - 1, items=[], next=0,
                               asked=now, partial=False)
            self.request(frm, mtype, 0)
        elif t == "MISSION_WRITE_PARTIAL_LIST" and self.kind == "ardupilot":
            stored = self.plans.get(mtype, [])
            if not 0 <= msg.start_index <= msg.end_index < len(stored):
                self.ack(frm, mtype, mav.MAV_MISSION_ERROR)
                return
            self.upload = dict(peer=frm, type=mtype, first=msg.start_index, last=msg.end_index, items=[],
                               next=msg.start_index, asked=now, partial=True)
            self.request(frm, mtype, msg.start_index)
        elif t == "MISSION_ITEM_INT":
            up = self.upload
            if not up or frm != up["peer"] or mtype != up["type"]:
                return
            if msg.seq != up["next"]:
                if self.kind == "ardupilot":
                    self.ack(frm, mtype, mav.MAV_MISSION_INVALID_SEQUENCE)
                return
            up["items"].append(item_of(msg))
            up["next"] += 1
            up["asked"] = now
            if up["next"] > up["last"]:
                self.upload = None
                self.storing = (now + self.store_delay, up)
            else:
                self.request(frm, mtype, up["next"])
        elif t == "MISSION_ACK" and msg.type == mav.MAV_MISSION_OPERATION_CANCELLED:
            if self.kind == "px4" and self.upload and self.upload["peer"] == frm:
                self.upload = None
        elif t == "MISSION_CLEAR_ALL":
            self.clears += 1
            if mtype == mav.MAV_MISSION_TYPE_ALL:
                self.plans = {MISSION: [], FENCE: []}
            else:
                self.plans[mtype] = []
            self.ack(frm, mtype, ACCEPTED, 0xC1EA if self.kind == "px4" else 0)

    def tick(self, now: float) -> None:
        if now >= self.next_hb:
            self.next_hb = now + 1.0
            autopilot = mav.MAV_AUTOPILOT_ARDUPILOTMEGA if self.kind == "ardupilot" else mav.MAV_AUTOPILOT_PX4
            self.send(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_QUADROTOR, autopilot, 0, 0, mav.MAV_STATE_ACTIVE, 3))
        if self.storing and now >= self.storing[0]:
            up = self.storing[1]
            self.storing = None
            stored = list(self.plans.get(up["type"], []))
            if up["partial"]:
                for k, it in enumerate(up["items"]):
                    stored[up["first"] + k] = it
            else:
                stored = up["items"]
            self.plans[up["type"]] = stored
            self.accepted.append((up["type"], stored))
            opaque = 0 if self.kind == "ardupilot" else 0x5EED
            self.ack(up["peer"], up["type"], ACCEPTED, opaque)
            backlog, self.backlog = self.backlog, []
            for msg in backlog:
                self.handle(msg, now)
        up = self.upload
        retry = 1.0 if self.kind == "ardupilot" else 0.25
        if up and now - up["asked"] > retry:
            up["asked"] = now
            self.request(up["peer"], up["type"], up["next"])


class Ground:
    """A ground station on the router's UDP port (or a second one on another port)."""

    def __init__(self, conn, ids=GCS, rule: str = "spec", timeout: float = 1.5, retries: int = 5):
        self.conn, self.ids, self.rule, self.timeout, self.retries = conn, ids, rule, timeout, retries
        self.up = None
        self.result = None
        self.got = []  # every mission message from the vehicle side
        self.heartbeat = False
        self.requests = 0

    def send(self, msg) -> None:
        self.conn.mav.send(msg)

    def upload(self, items: list[dict], mtype: int = MISSION, legacy: bool = False) -> None:
        self.result = None
        self.up = dict(items=items, type=mtype, next=0, retries=0, at=time.monotonic(), legacy=legacy)
        self.send(mav.MAVLink_mission_count_message(VEHICLE[0], VEHICLE[1], len(items), mtype))

    def send_item(self, seq: int) -> None:
        it, up = self.up["items"][seq], self.up
        if up["legacy"]:
            self.send(mav.MAVLink_mission_item_message(
                VEHICLE[0], VEHICLE[1], seq, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT, it["command"], 0, 1,
                0, 0, 0, 0, it["x"] * 1e-7, it["y"] * 1e-7, it["z"], up["type"]))
        else:
            self.send(mav.MAVLink_mission_item_int_message(
                VEHICLE[0], VEHICLE[1], seq, it["frame"], it["command"], 0, 1, 0, 0, 0, 0,
                it["x"], it["y"], it["z"], up["type"]))

    def poll(self, now: float, msgs: list) -> None:
        for msg in msgs:
            t = msg.get_type()
            if t == "HEARTBEAT" and msg.get_srcSystem() == VEHICLE[0]:
                self.heartbeat = True
            if not t.startswith("MISSION_"):
                continue
            self.got.append(msg)
            if getattr(msg, "target_system", 0) != self.ids[0]:
                continue
            up = self.up
            if up is None:
                continue
            if t == "MISSION_REQUEST_INT" and msg.mission_type == up["type"] and msg.seq < len(up["items"]):
                self.requests += 1
                if msg.seq >= up["next"]:
                    # MAVSDK counts the first send of an item as one of its tries too
                    up["retries"], up["next"] = int(self.rule == "mavsdk"), msg.seq + 1
                elif self.rule == "mavsdk":
                    if up["retries"] >= self.retries:
                        self.up, self.result = None, "mavsdk-retries"
                        continue
                    up["retries"] += 1
                up["at"] = now
                self.send_item(msg.seq)
            elif t == "MISSION_ACK" and msg.mission_type == up["type"]:
                self.up, self.result = None, msg.type
        up = self.up
        if up and now - up["at"] > self.timeout:
            if up["retries"] >= self.retries:
                self.up, self.result = None, "timeout"
                return
            up["retries"] += 1
            up["at"] = now
            if up["next"] == 0:
                self.send(mav.MAVLink_mission_count_message(VEHICLE[0], VEHICLE[1], len(up["items"]), up["type"]))
            elif self.rule == "spec":
                self.send_item(up["next"] - 1)

    def acks(self) -> list[int]:
        return [m.type for m in self.got if m.get_type() == "MISSION_ACK" and m.target_system == self.ids[0]]


class World:
    def __init__(self, fc: Autopilot, grounds: list[Ground]):
        self.fc, self.grounds = fc, grounds

    def step(self) -> None:
        select.select([self.fc.fd], [], [], 0.005)
        now = time.monotonic()
        self.fc.read(now)
        self.fc.tick(now)
        # The router sends every frame to each ground station it accepted: each hears its
        # own socket.
        heard = {}
        for g in self.grounds:
            if id(g.conn) not in heard:
                heard[id(g.conn)] = []
                while (msg := g.conn.recv_match(blocking=False)) is not None:
                    heard[id(g.conn)].append(msg)
            g.poll(now, heard[id(g.conn)])

    def run(self, seconds: float, until=None) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.step()
            if until and until():
                return True
        return False


def scenario_ardupilot(w: World, checks: dict) -> None:
    fc, g = w.fc, w.grounds[0]
    # 1: the autopilot's ACCEPTED (opaque_id 0) to the ground while it uploads never answers it
    fc.plans[MISSION] = plan(3, 0)
    g.upload(plan(6, 77))
    for _ in range(3):
        w.run(0.05)
        fc.ack(GCS, MISSION, ACCEPTED)
    w.run(20, lambda: g.result is not None)
    checks["stray_ack_not_taken"] = (g.result == ACCEPTED and g.acks() == [ACCEPTED]
                                     and same(fc.plans[MISSION], plan(6, 77)), [g.result, g.acks()])
    # 2: the autopilot stores plan A slowly; the ground uploads B meanwhile
    fc.store_delay = 1.5
    g.got.clear()
    g.upload(plan(8, 1))
    w.run(20, lambda: fc.storing is not None)
    g.upload(plan(5, 2))
    w.run(30, lambda: g.result is not None)
    w.run(3)
    fc.store_delay = 0.0
    checks["slow_store_then_next_plan"] = (g.result == ACCEPTED and same(fc.plans[MISSION], plan(5, 2)),
                                           [g.result, len(fc.plans[MISSION])])
    # 5: a partial write completes
    g.got.clear()
    g.send(mav.MAVLink_mission_write_partial_list_message(VEHICLE[0], VEHICLE[1], 1, 2, MISSION))
    new = plan(5, 900)
    end = time.monotonic() + 15
    answered = 0
    while time.monotonic() < end and not g.acks():
        w.step()
        asked = [m.seq for m in g.got if m.get_type() == "MISSION_REQUEST_INT"]
        for seq in asked[answered:]:
            answered += 1
            it = new[seq]
            g.send(mav.MAVLink_mission_item_int_message(VEHICLE[0], VEHICLE[1], seq, it["frame"], it["command"],
                                                        0, 1, 0, 0, 0, 0, it["x"], it["y"], it["z"], MISSION))
    want = plan(5, 2)
    want[1], want[2] = new[1], new[2]
    checks["partial_write"] = (g.acks() == [ACCEPTED] and same(fc.plans[MISSION], want), [g.acks(), answered])
    # 5: a legacy MISSION_ITEM upload is refused, nothing of it reaches the autopilot
    counts = fc.counts
    g.upload(plan(3, 5), legacy=True)
    w.run(20, lambda: g.result is not None)
    checks["legacy_item_refused"] = (g.result == mav.MAV_MISSION_UNSUPPORTED and fc.counts == counts
                                     and same(fc.plans[MISSION], want), [g.result, fc.counts - counts])


def scenario_px4(w: World, checks: dict) -> None:
    fc, g, sdk = w.fc, w.grounds[0], w.grounds[1]
    # 5: a clear-all's ack naming the cleared plan reaches the ground
    fc.plans[MISSION] = plan(3, 0)
    g.send(mav.MAVLink_mission_clear_all_message(VEHICLE[0], VEHICLE[1], MISSION))
    w.run(10, lambda: g.acks())
    checks["clear_all_ack_with_id"] = (g.acks() == [ACCEPTED] and fc.plans[MISSION] == [], g.acks())
    # 6: MAVSDK (0.5 s, 5 retries, each repeated request a retry) waits for a vehicle that
    # takes 1.5 s to store
    fc.store_delay = 1.5
    sdk.upload(plan(20, 4))
    w.run(30, lambda: sdk.result is not None)
    fc.store_delay = 0.0
    checks["mavsdk_upload"] = (sdk.result == ACCEPTED and same(fc.plans[MISSION], plan(20, 4))
                               and sdk.requests == 20, [sdk.result, sdk.requests])
    # 7: a second ground's count mid-upload is refused and the first upload completes
    g.got.clear()
    g.upload(plan(10, 6))
    w.run(0.02)
    sdk.upload(plan(10, 7))
    w.run(30, lambda: g.result is not None and sdk.result is not None)
    checks["second_ground_refused"] = (g.result == ACCEPTED and sdk.result == mav.MAV_MISSION_DENIED
                                       and same(fc.plans[MISSION], plan(10, 6)), [g.result, sdk.result])


def scenario_mavlink1(w: World, checks: dict) -> None:
    fc, g = w.fc, w.grounds[0]
    fc.plans[MISSION] = plan(4, 5)
    g.send(mav.MAVLink_mission_clear_all_message(VEHICLE[0], VEHICLE[1], FENCE))
    w.run(10, lambda: g.acks())
    checks["fence_clear_all_refused"] = (g.acks() == [mav.MAV_MISSION_UNSUPPORTED] and fc.clears == 0
                                         and same(fc.plans[MISSION], plan(4, 5)), [g.acks(), fc.clears])
    for n in (0, 3):
        g.upload(plan(n, 9, FENCE), FENCE)
        w.run(20, lambda: g.result is not None)
        checks[f"fence_upload_{n}_refused"] = (g.result == mav.MAV_MISSION_UNSUPPORTED and fc.counts == 0
                                               and same(fc.plans[MISSION], plan(4, 5)), [g.result, fc.counts])
    g.upload(plan(3, 11))
    w.run(20, lambda: g.result is not None)
    checks["mission_upload"] = (g.result == ACCEPTED and same(fc.plans[MISSION], plan(3, 11)), g.result)


def scenario_restart(w: World, checks: dict) -> None:
    fc, g = w.fc, w.grounds[0]
    a = plan(6, 3)
    g.upload(a)
    w.run(20, lambda: g.result is not None)
    first = g.result
    g.send(mav.MAVLink_mission_clear_all_message(VEHICLE[0], VEHICLE[1], MISSION))
    w.run(10, lambda: g.acks()[-1:] == [ACCEPTED] and not fc.plans[MISSION])
    emit({"event": "restart-router"})
    sys.stdin.readline()
    w.run(20, lambda: g.heartbeat)
    w.run(3)
    counts = fc.counts
    g.upload(a)
    w.run(30, lambda: g.result is not None)
    checks["upload_after_clear_and_router_restart"] = (
        first == ACCEPTED and g.result == ACCEPTED and fc.counts == counts + 1 and same(fc.plans[MISSION], a),
        [first, g.result, fc.counts - counts, len(fc.plans[MISSION])])


SCENARIOS = {
    "ardupilot": ("ardupilot", False, scenario_ardupilot),
    "px4": ("px4", False, scenario_px4),
    "mavlink1": ("ardupilot", True, scenario_mavlink1),
    "restart": ("ardupilot", False, scenario_restart),
}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", required=True, choices=sorted(SCENARIOS))
    ap.add_argument("--udp", required=True, help="host:port the router sends the ground stations")
    args = ap.parse_args()
    kind, v1, run = SCENARIOS[args.scenario]
    fc = Autopilot(kind, v1, 0.0)
    conn = mavutil.mavlink_connection("udpin:" + args.udp, source_system=GCS[0], source_component=GCS[1],
                                      dialect="common")
    grounds = [Ground(conn)]
    w = World(fc, grounds)
    emit({"port": fc.port})
    checks: dict = {}
    if not w.run(30, lambda: grounds[0].heartbeat):
        checks["vehicle_heard"] = (False, "no heartbeat through the router")
    else:
        # one heartbeat out of the ground, so the router knows where to send
        conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        w.run(2)
        if args.scenario == "px4":
            # MAVSDK's ground station (system 245) on a socket of its own, to the router's
            # address; the router sends to it once it has spoken
            host, port = next(iter(conn.clients))
            sdk_conn = mavutil.mavlink_connection(f"udpout:{host}:{port}", source_system=MAVSDK[0],
                                                  source_component=MAVSDK[1], dialect="common")
            grounds.append(Ground(sdk_conn, MAVSDK, "mavsdk", 0.5, 5))
        run(w, checks)
    emit({"checks": {k: [bool(v[0]), v[1]] for k, v in checks.items()},
          "ok": bool(checks) and all(v[0] for v in checks.values())})
    return 0


if __name__ == "__main__":
    sys.exit(main())
