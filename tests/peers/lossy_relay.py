#!/usr/bin/env python3
"""A bad wire between an EtherCAT master and gantry-sim, for tests.

Usage: lossy_relay.py MASTER_IF SIM_IF --mailbox-in 0x1080 --drop-every 5

Forwards EtherCAT frames (EtherType 0x88A4) both ways between two interfaces and drops
every Nth frame coming back from the simulator that carries a successful physical read
(FPRD/APRD, WKC > 0) of the read mailbox at the given address: the master loses a mailbox
answer after the slave has handed it out, the case the ESC's repeat request is for.
Prints "relay: ready" once both sockets are bound and one line per dropped frame.
"""

import argparse
import select
import socket
import struct
import sys

ETHERTYPE = 0x88A4
FPRD, APRD = 0x04, 0x01


def open_if(name):
    s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETHERTYPE))
    s.bind((name, 0))
    return s


def reads_mailbox(frame, mailbox):
    """Whether a datagram of `frame` is a successful FPRD/APRD starting at `mailbox`."""
    if len(frame) < 16 or struct.unpack_from(">H", frame, 12)[0] != ETHERTYPE:
        return False
    at, end = 16, 16 + (struct.unpack_from("<H", frame, 14)[0] & 0x07FF)
    while at + 12 <= min(end, len(frame)):
        cmd = frame[at]
        ado = struct.unpack_from("<H", frame, at + 4)[0]
        flags = struct.unpack_from("<H", frame, at + 6)[0]
        n = flags & 0x07FF
        if at + 10 + n + 2 > len(frame):
            return False
        wkc = struct.unpack_from("<H", frame, at + 10 + n)[0]
        if cmd in (FPRD, APRD) and ado == mailbox and wkc > 0:
            return True
        if not flags & 0x8000:  # no more datagrams
            return False
        at += 10 + n + 2
    return False


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("master_if")
    p.add_argument("sim_if")
    p.add_argument("--mailbox-in", type=lambda v: int(v, 0), required=True)
    p.add_argument("--drop-every", type=int, default=5)
    a = p.parse_args()
    to_master, to_sim = open_if(a.master_if), open_if(a.sim_if)
    print("relay: ready", flush=True)
    seen = dropped = 0
    while True:
        ready, _, _ = select.select([to_master, to_sim], [], [])
        for s in ready:
            frame, addr = s.recvfrom(9216)
            if addr[2] == socket.PACKET_OUTGOING:
                continue
            if s is to_sim:
                if reads_mailbox(frame, a.mailbox_in):
                    seen += 1
                    if seen % a.drop_every == 0:
                        dropped += 1
                        print(f"relay: dropped mailbox answer {seen} ({dropped} dropped)", flush=True)
                        continue
                to_master.send(frame)
            else:
                to_sim.send(frame)


if __name__ == "__main__":
    sys.exit(main())
