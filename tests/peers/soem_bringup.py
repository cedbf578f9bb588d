#!/usr/bin/env python3
"""SOEM (through pysoem) as a second, independent EtherCAT master against gantry-sim.

Usage: soem_bringup.py IFACE [--seconds 1.5] [--cycle-us 1000] [--late-frames-percent 2]

Scans the network, prints every slave, has slave 0 request an invalid transition
(PREOP->OP: refused with AL status code 0x0011, cleared by an acknowledge), looks for
distributed clocks (config_dc; the simulated servos have DC), maps the process data, walks the
slaves to SAFEOP and OP the way SOEM's examples do, exchanges process data checking the
working counter every cycle (a frame that comes back with another working counter is an
error; one not back within 5 ms is counted as late: the machine is shared), reads
0x1018:01 and 0x1C12 by SDO, enables every CiA-402 servo with the controlword sequence
0x0006/0x0007/0x000F and checks the statusword, then stops sending for 300 ms and checks
that the process-data watchdog took every slave to SAFEOP with AL status code 0x001B and
faulted its drive. Human-readable lines go to stderr; the last line on stdout is one JSON
object with the results. Exits non-zero on any failure.

This is a test peer run as its own process (pysoem/SOEM are GPL): nothing of it is linked
into gantry.
"""

import argparse
import json
import struct
import sys
import time

import pysoem

# Process data of the simulated servo (sim-slave/src/plant/servo.rs):
# outputs controlword u16 + target position i32, inputs statusword u16 + position i32.
OUT = struct.Struct("<Hi")
IN = struct.Struct("<Hi")
STATE_NAMES = {
    pysoem.NONE_STATE: "NONE",
    pysoem.INIT_STATE: "INIT",
    pysoem.PREOP_STATE: "PREOP",
    pysoem.BOOT_STATE: "BOOT",
    pysoem.SAFEOP_STATE: "SAFEOP",
    pysoem.OP_STATE: "OP",
}


def log(*args):
    print(*args, file=sys.stderr, flush=True)


def state_name(s):
    err = "+ERROR" if s & pysoem.STATE_ERROR else ""
    return STATE_NAMES.get(s & 0x0F, hex(s)) + err


class Bringup:
    def __init__(self, ifname, seconds, cycle_us, late_frames_percent):
        self.ifname = ifname
        self.late_frames_percent = late_frames_percent
        self.seconds = seconds
        self.cycle_s = cycle_us / 1e6
        self.master = pysoem.Master()
        self.r = {
            "ok": False,
            "stage": "open",
            "errors": [],
            "slaves": [],
            "dc": None,
            "expected_wkc": None,
            "cycles": 0,
            "wkc_errors": 0,
            "late_frames": 0,
            "wkc_seen": {},
            "reached_safeop": False,
            "reached_op": False,
            "enabled": [],
            "round_trip_us": {},
            "stage_seconds": {},
        }
        self.rtt = []

    def fail(self, msg):
        self.r["errors"].append(f"{self.r['stage']}: {msg}")
        log("FAIL", self.r["stage"], msg)

    def cycle(self):
        """One exchange: send, receive, check the working counter."""
        t0 = time.perf_counter()
        self.master.send_processdata()
        wkc = self.master.receive_processdata(5000)
        self.rtt.append(time.perf_counter() - t0)
        self.r["cycles"] += 1
        key = str(wkc)
        self.r["wkc_seen"][key] = self.r["wkc_seen"].get(key, 0) + 1
        if wkc < 0:
            # No frame within the timeout (SOEM: EC_NOFRAME): late, not wrong.
            self.r["late_frames"] += 1
        elif wkc != self.master.expected_wkc:
            self.r["wkc_errors"] += 1
            if "first_wkc_error" not in self.r:
                self.r["first_wkc_error"] = {"cycle": self.r["cycles"], "wkc": wkc, "stage": self.r["stage"]}
        return wkc

    def run(self):
        m = self.master
        m.open(self.ifname)
        try:
            stages = (self.scan, self.map_and_safeop, self.to_op, self.sdo, self.exchange_and_enable, self.watchdog)
            for stage in stages:
                t0 = time.perf_counter()
                stage()
                self.r["stage_seconds"][stage.__name__] = round(time.perf_counter() - t0, 3)
                if self.r["errors"]:
                    break
        except Exception as e:  # a pysoem exception is a failure with its text
            self.fail(f"{type(e).__name__}: {e}")
        finally:
            self.r["stage"] = "close"
            try:
                m.state = pysoem.INIT_STATE
                m.write_state()
            except Exception as e:
                log("leaving INIT:", e)
            m.close()
        if self.rtt:
            s = sorted(self.rtt)
            self.r["round_trip_us"] = {
                "mean": round(1e6 * sum(s) / len(s), 1),
                "p50": round(1e6 * s[len(s) // 2], 1),
                "p99": round(1e6 * s[min(len(s) - 1, int(len(s) * 0.99))], 1),
                "max": round(1e6 * s[-1], 1),
            }
        self.r["ok"] = not self.r["errors"]
        return self.r

    def scan(self):
        m = self.master
        self.r["stage"] = "config_init"
        n = m.config_init()
        log(f"config_init: {n} slaves")
        if n <= 0:
            self.fail("no slaves found")
            return
        for i, s in enumerate(m.slaves):
            addr = struct.unpack("<H", s._fprd(0x0010, 2, 2000))[0]
            info = {
                "position": i,
                "name": s.name,
                "vendor": s.man,
                "product": s.id,
                "revision": s.rev,
                "address": addr,
                "state": state_name(s.state),
            }
            self.r["slaves"].append(info)
            log(
                f"slave {i}: {s.name!r} vendor 0x{s.man:08X} product 0x{s.id:08X} "
                f"rev {s.rev} address 0x{addr:04X} state {state_name(s.state)}"
            )
        self.r["stage"] = "preop"
        if m.state_check(pysoem.PREOP_STATE, 50_000) != pysoem.PREOP_STATE:
            self.fail("not all slaves in PREOP: " + self.states())
        self.each_in(pysoem.PREOP_STATE, "state")
        for i, s in enumerate(m.slaves):
            self.r["slaves"][i]["al_status_code"] = s.al_status
        if not self.r["errors"]:
            self.refused_transition()

    def refused_transition(self):
        """PREOP -> OP skips SAFEOP: the slave must refuse it with the error flag and AL
        status code 0x0011, keep it until acknowledged, and clear it on PREOP + ACK."""
        self.r["stage"] = "refused_transition"
        m, s = self.master, self.master.slaves[0]
        s.state = pysoem.OP_STATE
        s.write_state()
        s.state_check(pysoem.PREOP_STATE | pysoem.STATE_ERROR, 50_000)
        m.read_state()
        refused = {"state": state_name(s.state), "al_status_code": s.al_status}
        s.state = pysoem.PREOP_STATE | pysoem.STATE_ACK
        s.write_state()
        s.state_check(pysoem.PREOP_STATE, 50_000)
        m.read_state()
        refused.update(after_ack=state_name(s.state), code_after_ack=s.al_status)
        self.r["refused_transition"] = refused
        log(f"slave 0: PREOP->OP refused: {refused}")
        if refused["state"] != "PREOP+ERROR" or refused["al_status_code"] != 0x0011:
            self.fail(f"PREOP->OP not refused with 0x0011: {refused}")
        if refused["after_ack"] != "PREOP":
            self.fail(f"error not cleared by PREOP+ACK: {refused}")

    def each_in(self, state, key):
        """Reads every slave's AL status on its own (FPRD) and checks it is `state`: the
        group check above is one broadcast read, which hides a slave that does not answer."""
        self.master.read_state()
        for i, s in enumerate(self.master.slaves):
            self.r["slaves"][i][key] = state_name(s.state)
            if s.state != state:
                self.fail(f"slave {i} reads {state_name(s.state)}, expected {state_name(state)}")

    def states(self):
        self.master.read_state()
        return ", ".join(
            f"{i}:{state_name(s.state)} AL 0x{s.al_status:04X} ({pysoem.al_status_code_to_string(s.al_status)})"
            for i, s in enumerate(self.master.slaves)
        )

    def map_and_safeop(self):
        m = self.master
        # The simulated servos emulate distributed clocks: config_dc must find them
        # (SOEM latches receive times, computes delays and writes offsets).
        self.r["stage"] = "config_dc"
        self.r["dc"] = bool(m.config_dc())
        log(f"config_dc: DC {'found' if self.r['dc'] else 'not found'}")
        self.r["stage"] = "config_map"
        size = m.config_map()
        self.r["iomap_bytes"] = size
        self.r["expected_wkc"] = m.expected_wkc
        log(f"config_map: IOmap {size} bytes, expected WKC {m.expected_wkc}")
        for i, s in enumerate(m.slaves):
            info = self.r["slaves"][i]
            info["ibytes"] = len(s.input)
            info["obytes"] = len(s.output)
            log(f"slave {i}: Ibytes {info['ibytes']} Obytes {info['obytes']}")
            if info["ibytes"] < IN.size or info["obytes"] < OUT.size:
                # Writing outputs the mapping does not have would crash pysoem.
                self.fail(f"slave {i} mapped {info['obytes']}/{info['ibytes']} bytes, expected {OUT.size}/{IN.size}")
        if self.r["errors"]:
            return
        self.r["stage"] = "safeop"
        if m.state_check(pysoem.SAFEOP_STATE, 50_000) != pysoem.SAFEOP_STATE:
            self.fail("not all slaves in SAFEOP: " + self.states())
            return
        self.each_in(pysoem.SAFEOP_STATE, "state_safeop")
        self.r["reached_safeop"] = not self.r["errors"]

    def to_op(self):
        m = self.master
        self.r["stage"] = "op"
        for s in m.slaves:
            s.output = OUT.pack(0, 0)
        m.state = pysoem.OP_STATE
        # As SOEM's simple_test: one exchange so that the outputs are valid, request OP,
        # then keep exchanging while checking the state.
        self.cycle()
        m.write_state()
        for _ in range(200):
            self.cycle()
            m.state_check(pysoem.OP_STATE, 5_000)
            if m.state == pysoem.OP_STATE:
                break
            time.sleep(self.cycle_s)
        if m.state != pysoem.OP_STATE:
            self.fail("not all slaves in OP: " + self.states())
            return
        self.each_in(pysoem.OP_STATE, "state_op")
        self.r["reached_op"] = not self.r["errors"]
        log("all slaves in OP")

    def sdo(self):
        self.r["stage"] = "sdo"
        vendors, assign = [], []
        for i, s in enumerate(self.master.slaves):
            self.cycle()  # keep the process-data watchdog fed
            vendors.append(struct.unpack("<I", s.sdo_read(0x1018, 1))[0])
            n = struct.unpack("<B", s.sdo_read(0x1C12, 0))[0]
            pdos = [struct.unpack("<H", s.sdo_read(0x1C12, k))[0] for k in range(1, n + 1)]
            assign.append(pdos)
            log(f"slave {i}: SDO 0x1018:01 = 0x{vendors[-1]:08X}, 0x1C12 = {[hex(p) for p in pdos]}")
        self.r["sdo_vendor"] = vendors
        self.r["sdo_1c12"] = assign

    def exchange_and_enable(self):
        m = self.master
        self.r["stage"] = "exchange"
        slaves = m.slaves
        n = len(slaves)
        status = [0] * n
        position = [0] * n
        enabled_at = [None] * n
        steps = [0x0006, 0x0007, 0x000F]
        step = [0] * n
        t_end = time.perf_counter() + self.seconds
        next_t = time.perf_counter()
        while time.perf_counter() < t_end:
            for i, s in enumerate(slaves):
                sw, pos = IN.unpack(bytes(s.input)[: IN.size])
                status[i], position[i] = sw, pos
                if sw & 0x4F == 0x08:  # fault: reset it
                    cw = 0x0080
                elif sw & 0x4F == 0x40:  # switch on disabled
                    step[i] = 0
                    cw = steps[0]
                else:
                    want = {0x21: 1, 0x23: 2, 0x27: 2}.get(sw & 0x6F, step[i])
                    step[i] = max(step[i], want)
                    cw = steps[step[i]]
                    if sw & 0x6F == 0x27 and enabled_at[i] is None:
                        enabled_at[i] = self.r["cycles"]
                # Hold the actual position: CSP must not jump when enabled.
                s.output = OUT.pack(cw, pos)
            self.cycle()
            next_t += self.cycle_s
            delay = next_t - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
        m.read_state()
        for i, s in enumerate(slaves):
            info = self.r["slaves"][i]
            info["statusword"] = status[i]
            info["position_actual"] = position[i]
            info["enabled_at_cycle"] = enabled_at[i]
            info["state_after"] = state_name(s.state)
            log(f"slave {i}: statusword 0x{status[i]:04X} position {position[i]} state {state_name(s.state)}")
        self.r["enabled"] = [sw & 0x6F == 0x27 for sw in status]
        if not all(self.r["enabled"]):
            self.fail(f"not every servo is Operation enabled: statuswords {[hex(x) for x in status]}")
        if any(s.state != pysoem.OP_STATE for s in slaves):
            self.fail("a slave left OP: " + self.states())
        if self.r["wkc_errors"]:
            self.fail(f"{self.r['wkc_errors']} working-counter errors in {self.r['cycles']} cycles")
        if self.r["late_frames"] * 100 > self.late_frames_percent * self.r["cycles"]:
            self.fail(f"{self.r['late_frames']} frames late in {self.r['cycles']} cycles")

    def watchdog(self):
        """Stop sending process data for 300 ms in OP: every slave's process-data watchdog
        (100 ms by default) must take it to SAFEOP with the error flag and AL status code
        0x001B, its drive must fault; an acknowledge clears the error."""
        m = self.master
        self.r["stage"] = "watchdog"
        time.sleep(0.3)
        m.read_state()
        seen = [(state_name(s.state), s.al_status) for s in m.slaves]
        self.cycle()  # inputs are still valid in SAFEOP
        faulted = [IN.unpack(bytes(s.input)[: IN.size])[0] & 0x4F == 0x08 for s in m.slaves]
        for s in m.slaves:
            s.state = pysoem.SAFEOP_STATE | pysoem.STATE_ACK
            s.write_state()
        m.state_check(pysoem.SAFEOP_STATE, 50_000)
        m.read_state()
        after = [state_name(s.state) for s in m.slaves]
        self.r["watchdog"] = {"tripped": seen, "drive_faulted": faulted, "after_ack": after}
        log(f"watchdog: {self.r['watchdog']}")
        if any(st != "SAFEOP+ERROR" or code != 0x001B for st, code in seen):
            self.fail(f"the process-data watchdog did not take every slave to SAFEOP+ERROR 0x001B: {seen}")
        if not all(faulted):
            self.fail(f"not every drive faulted: {faulted}")
        if any(a != "SAFEOP" for a in after):
            self.fail(f"acknowledge did not clear the error: {after}")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("interface")
    p.add_argument("--seconds", type=float, default=1.5)
    p.add_argument("--cycle-us", type=int, default=1000)
    p.add_argument(
        "--late-frames-percent",
        type=float,
        default=2.0,
        help="frames of the exchange that may come back late (>5 ms) on a shared machine",
    )
    a = p.parse_args()
    r = Bringup(a.interface, a.seconds, a.cycle_us, a.late_frames_percent).run()
    print(json.dumps(r), flush=True)
    return 0 if r["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
