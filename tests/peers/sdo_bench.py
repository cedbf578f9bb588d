#!/usr/bin/env python3
"""python-canopen's SDO client uploading one object from a node, timed, block and segmented.

Usage: sdo_bench.py CHANNEL --node N --index 0x2F00 --out DIR [--runs 3] [--segmented-runs 1]

On the SocketCAN interface CHANNEL: uploads INDEX:00 of node N with python-canopen's
block upload (`SdoClient.open(..., block_transfer=True)`: sub-blocks of 127, CRC asked
for) --runs times, then with its normal upload (`SdoClient.upload`, segmented for an
object over 4 bytes) --segmented-runs times, each timed from the request to the last
byte (time.perf_counter). The bytes of the last upload of each kind go to
DIR/python-block.bin and DIR/python-segmented.bin, for the caller to check byte for byte.
The last line on stdout is one JSON object: {"block": {"seconds": [...], "bytes": N},
"segmented": {...}}. Exits non-zero on any failure.
"""

import argparse
import json
import os
import socket
import sys
import time

import canopen


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("channel")
    p.add_argument("--node", type=int, required=True)
    p.add_argument("--index", type=lambda s: int(s, 0), required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--segmented-runs", type=int, default=1)
    a = p.parse_args()
    network = canopen.Network()
    network.connect(interface="socketcan", channel=a.channel)
    # vcan has no bit timing: a sub-block of 127 segments arrives at once, faster than
    # python-can's receive thread takes frames in an emulated VM, and frames beyond the
    # socket's receive buffer (~200 KiB by default, a few hundred frames) are dropped
    # (measured: repeated retransmissions, then the server's timeout). On a real bus
    # they come at most 7 a millisecond. A larger buffer (SO_RCVBUFFORCE, as root in the
    # VM) keeps the harness from losing what the client would have got.
    sock = network.bus.socket
    try:
        sock.setsockopt(socket.SOL_SOCKET, 33, 16 << 20)  # SO_RCVBUFFORCE
    except OSError:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16 << 20)
    log(f"receive buffer {sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)} bytes")
    try:
        # No EDS: a raw upload of the object's bytes.
        node = canopen.RemoteNode(a.node, canopen.ObjectDictionary())
        network.add_node(node)
        # The emulated VM is slow: more than python-canopen's 0.3 s between frames. 30 s,
        # as gantry's client has and the node (`sdo_timeout_ms`, sdo_bench_vcan.rs).
        node.sdo.RESPONSE_TIMEOUT = 30.0
        # Progress on stderr every 1270 answers (ten sub-blocks), so that a run that
        # fails still tells how fast it went.
        plain = node.sdo.read_response
        seen = {"n": 0, "t0": time.perf_counter()}

        def counted():
            r = plain()
            seen["n"] += 1
            if seen["n"] % 1270 == 0:
                log(f"{seen['n']} answers in {time.perf_counter() - seen['t0']:.1f} s")
            return r

        node.sdo.read_response = counted
        results = {}
        for mode, runs in (("block", a.runs), ("segmented", a.segmented_runs)):
            seconds = []
            data = b""
            for _ in range(runs):
                seen["n"], seen["t0"] = 0, time.perf_counter()
                t0 = time.perf_counter()
                if mode == "block":
                    with node.sdo.open(a.index, 0, "rb", block_transfer=True) as f:
                        data = f.read()
                else:
                    data = node.sdo.upload(a.index, 0)
                seconds.append(time.perf_counter() - t0)
                log(f"python-canopen {mode}: {len(data)} bytes in {seconds[-1]:.3f} s")
            with open(os.path.join(a.out, f"python-{mode}.bin"), "wb") as f:
                f.write(data)
            results[mode] = {"seconds": seconds, "bytes": len(data)}
        print(json.dumps(results), flush=True)
    finally:
        network.disconnect()


if __name__ == "__main__":
    main()
