#!/usr/bin/env python3
"""python-canopen's LocalNode as an independent CANopen node for gantry's master side.

Usage: canopen_node.py CHANNEL --node N [--heartbeat-ms 100] [--domain-bytes 1000]

On the SocketCAN interface CHANNEL: a node with its own object dictionary — 0x1000
device type, 0x1008 device name (VISIBLE_STRING), 0x1017 producer heartbeat time,
0x2100 a DOMAIN of --domain-bytes bytes (byte i = i % 251), 0x2101 an UNSIGNED32 — served
by python-canopen's SDO server (expedited and segmented; it has no block server). It
sends its boot-up message, enters pre-operational and sends heartbeats every
--heartbeat-ms; NMT commands change the state its heartbeats report. It prints "ready" on
stdout once it listens, runs until its standard input closes, then prints one JSON object
with what the master left in 0x2100 (hex) and 0x2101 and its NMT state. Human-readable
lines go to stderr.
"""

import argparse
import json
import sys

import canopen
from canopen.objectdictionary import ODVariable
from canopen.objectdictionary import datatypes as dt


def variable(name, index, data_type, access, default=None):
    v = ODVariable(name, index, 0)
    v.data_type = data_type
    v.access_type = access
    v.default = default
    return v


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("channel")
    p.add_argument("--node", type=int, required=True)
    p.add_argument("--heartbeat-ms", type=int, default=100)
    p.add_argument("--domain-bytes", type=int, default=1000)
    a = p.parse_args()

    od = canopen.ObjectDictionary()
    od.add_object(variable("Device type", 0x1000, dt.UNSIGNED32, "ro", 0x0000_0191))
    od.add_object(variable("Manufacturer device name", 0x1008, dt.VISIBLE_STRING, "const",
                           "python-canopen LocalNode"))
    od.add_object(variable("Producer heartbeat time", 0x1017, dt.UNSIGNED16, "rw",
                           a.heartbeat_ms))
    od.add_object(variable("Test domain", 0x2100, dt.DOMAIN, "rw"))
    od.add_object(variable("Test value", 0x2101, dt.UNSIGNED32, "rw", 0))

    network = canopen.Network()
    network.connect(interface="socketcan", channel=a.channel)
    try:
        node = canopen.LocalNode(a.node, od)
        network.add_node(node)
        node.set_data(0x2100, 0, bytes(i % 251 for i in range(a.domain_bytes)))
        # Boot-up, then pre-operational with heartbeats (0x1017).
        node.nmt.state = "INITIALISING"
        node.nmt.state = "PRE-OPERATIONAL"
        print("ready", flush=True)
        print("node", a.node, "on", a.channel, "ready", file=sys.stderr, flush=True)
        sys.stdin.read()
        report = {
            "domain": node.get_data(0x2100, 0).hex(),
            "value": int.from_bytes(node.get_data(0x2101, 0), "little"),
            "nmt_state": node.nmt.state,
        }
        node.nmt.stop_heartbeat()
    finally:
        network.disconnect()
    print(json.dumps(report), flush=True)


if __name__ == "__main__":
    main()
