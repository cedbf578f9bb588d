#!/usr/bin/env python3
"""python-canopen as an independent CANopen master against gantry-sim --can.

Usage: canopen_master.py CHANNEL --node N --eds FILE [--cycle-ms 20] [--move 20000]

On the SocketCAN interface CHANNEL: resets node N and waits for its boot-up; SDO of
every kind python-canopen has (expedited, segmented and block upload of strings and
numbers; expedited, segmented and block download, each read back; an abort for an object
that does not exist); reads the PDO configuration and maps TPDO2 (position actual value,
statusword; synchronous) the way python-canopen saves a PDO; starts the node; then runs
the cycle itself from a thread, as a CiA 402 master must: every period RPDO1 (controlword,
target position) and then SYNC, so the drive takes each setpoint at the SYNC after it. The
CiA 402 state machine goes to Operation enabled through python-canopen's BaseNode402, in
cyclic synchronous position mode, and the axis moves by --move counts on a smooth profile
and stops; the drive's TPDOs report where it is. Human-readable lines go to stderr; the
last line on stdout is one JSON object with the results. Exits non-zero on any failure.

BaseNode402 treats a synchronous RPDO as periodic: its controlword setter only stores
the value and expects someone to send the RPDO. The cycle thread is that someone. The
subclass below only gives the state machine more time (the emulated VM is slow).
"""

import argparse
import json
import math
import sys
import threading
import time

import canopen
from canopen.profiles.p402 import BaseNode402


def log(*a):
    print(*a, file=sys.stderr, flush=True)


class Drive(BaseNode402):
    """BaseNode402 with timeouts for a slow (emulated) machine."""

    TIMEOUT_SWITCH_STATE_FINAL = 10.0
    TIMEOUT_SWITCH_STATE_SINGLE = 3.0
    TIMEOUT_CHECK_TPDO = 2.0
    TIMEOUT_SWITCH_OP_MODE = 3.0
    TIMEOUT_RESET_FAULT = 3.0


class Cycle(threading.Thread):
    """Every period: RPDO1 with the current controlword and target, then SYNC."""

    def __init__(self, network, rpdo, period):
        super().__init__(daemon=True)
        self.network, self.rpdo, self.period = network, rpdo, period
        self.stop_flag = threading.Event()
        self.lock = threading.Lock()
        self.target = None
        self.cycles = 0

    def set_target(self, target):
        with self.lock:
            self.target = target

    def run(self):
        next_t = time.monotonic()
        while not self.stop_flag.is_set():
            with self.lock:
                if self.target is not None:
                    self.rpdo[0x607A].raw = self.target
            self.rpdo.transmit()
            self.network.sync.transmit()
            self.cycles += 1
            next_t += self.period
            delay = next_t - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                next_t = time.monotonic()


def sdo_tests(node, r):
    sdo = node.sdo
    # Expedited upload (4 bytes).
    r["device_type"] = int.from_bytes(sdo.upload(0x1000, 0), "little")
    # Segmented upload (a 24-byte string), then the same by block with CRC.
    r["name_segmented"] = sdo.upload(0x1008, 0).decode()
    with sdo.open(0x1008, 0, "rb", block_transfer=True) as f:
        r["name_block"] = f.read().decode()
    # Downloads of each kind to 0x6065 (following error window, UNSIGNED32), read back.
    back = {}
    sdo.download(0x6065, 0, (1111).to_bytes(4, "little"))
    back["expedited"] = int.from_bytes(sdo.upload(0x6065, 0), "little")
    sdo.download(0x6065, 0, (2222).to_bytes(4, "little"), force_segment=True)
    back["segmented"] = int.from_bytes(sdo.upload(0x6065, 0), "little")
    with sdo.open(0x6065, 0, "wb", size=4, block_transfer=True) as f:
        f.write((3333).to_bytes(4, "little"))
    with sdo.open(0x6065, 0, "rb", block_transfer=True) as f:
        back["block"] = int.from_bytes(f.read(), "little")
    r["downloads"] = back
    # An abort from the server: the object does not exist.
    try:
        sdo.upload(0x5FFF, 0)
        r["abort_code"] = None
    except canopen.SdoAbortedError as e:
        r["abort_code"] = e.code
    # Through the EDS's data types: 0x1017 is UNSIGNED16.
    r["heartbeat_ms"] = sdo[0x1017].raw


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("channel")
    p.add_argument("--node", type=int, required=True)
    p.add_argument("--eds", required=True)
    p.add_argument("--cycle-ms", type=float, default=20.0)
    p.add_argument("--move", type=int, default=20000)
    a = p.parse_args()
    r = {}
    network = canopen.Network()
    network.connect(interface="socketcan", channel=a.channel)
    emcys = []
    cycle = None
    try:
        node = Drive(a.node, a.eds)
        network.add_node(node)
        node.emcy.add_callback(lambda e: emcys.append([e.code, e.register]))

        # NMT: reset node, boot-up. Listened for before the reset is sent: the node may
        # answer before python-canopen's wait_for_bootup starts waiting, and that call
        # only sees a boot-up that arrives after it (a race that failed 1 CI run in 3).
        booted = threading.Event()
        network.subscribe(
            0x700 + a.node,
            lambda _id, data, _t: booted.set() if bytes(data[:1]) == b"\x00" else None,
        )
        node.nmt.send_command(0x81)
        if not booted.wait(10):
            raise RuntimeError("no boot-up within 10 s of NMT reset node")
        r["bootup"] = True
        log("boot-up seen; NMT state", node.nmt.state)

        sdo_tests(node, r)
        log("SDO:", {k: r[k] for k in ("device_type", "name_segmented", "name_block", "downloads", "abort_code")})

        # PDOs: read what the node has, map TPDO2 and save it (python-canopen writes
        # it by the CiA 301 procedure: invalidate, clear, map, count, validate).
        node.tpdo.read()
        node.rpdo.read()
        t2 = node.tpdo[2]
        t2.clear()
        t2.add_variable(0x6064)
        t2.add_variable(0x6041)
        t2.cob_id = 0x280 + a.node
        t2.trans_type = 1
        t2.enabled = True
        t2.save()
        r["tpdo1"] = [v.index for v in node.tpdo[1]]
        r["rpdo1"] = [v.index for v in node.rpdo[1]]
        r["tpdo2_cob_id"] = node.sdo[0x1801][1].raw

        # CiA 402 through BaseNode402 (it reads the PDO set-up again and follows the
        # statusword from the TPDOs). Mode: cyclic synchronous position, by SDO.
        node.setup_402_state_machine()
        node.sdo[0x6060].raw = 8
        r["op_mode"] = node.sdo[0x6061].raw

        node.nmt.state = "OPERATIONAL"
        rpdo = node.rpdo[1]
        cycle = Cycle(network, rpdo, a.cycle_ms / 1000.0)
        # The first TPDOs tell where the axis is: hold it there while enabling.
        cycle.start()
        if node.tpdo[1].wait_for_reception(5) is None:
            raise RuntimeError("no TPDO1 after SYNC")
        start = node.tpdo[1][0x6064].raw
        cycle.set_target(start)
        r["start"] = start
        tpdo2_seen = t2.wait_for_reception(5)
        r["tpdo2"] = [t2[0].raw, t2[1].raw] if tpdo2_seen else None
        states = [node.state]
        for target_state in ("READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED"):
            node.state = target_state
            states.append(node.state)
        r["states"] = states
        log("states:", states)

        # A move of --move counts on a cosine profile over 2 s, then 1 s to settle.
        steps = int(2.0 / (a.cycle_ms / 1000.0))
        for i in range(steps + 1):
            s = 0.5 - 0.5 * math.cos(math.pi * i / steps)
            cycle.set_target(start + round(a.move * s))
            time.sleep(a.cycle_ms / 1000.0)
        time.sleep(1.0)
        node.tpdo[1].wait_for_reception(2)
        r["end"] = node.tpdo[1][0x6064].raw
        r["target"] = start + a.move
        r["state_after_move"] = node.state
        r["statusword"] = node.statusword
        node.state = "SWITCH ON DISABLED"
        r["state_disabled"] = node.state
        r["cycles"] = cycle.cycles
        cycle.stop_flag.set()
        cycle.join()
        cycle = None
        node.nmt.state = "PRE-OPERATIONAL"
        r["emcy"] = emcys
    finally:
        if cycle is not None:
            cycle.stop_flag.set()
            cycle.join()
        network.disconnect()
    print(json.dumps(r), flush=True)


if __name__ == "__main__":
    main()
