"""Listens on every drone's API-link port, as a MAVSDK per drone would, for
`sadesim bench --mavlink` runs that should pay for delivering all telemetry
(docs/performance.md, MAVLink). Counts datagrams and prints the rate at the end.

    python3 tests/bench/api_listeners.py --drones 250 --seconds 200 &

The ports follow the port plan (docs/architecture.md): 14540+i for drones 0-9, 14600+i
from drone 10 on. Stops by itself after --seconds.
"""
import argparse
import selectors
import socket
import time


def api_port(i: int) -> int:
    return 14540 + i if i < 10 else 14600 + i


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--drones", type=int, default=250)
    parser.add_argument("--seconds", type=float, default=120.0)
    parser.add_argument("--host", default="127.0.0.1")
    args = parser.parse_args()
    selector = selectors.DefaultSelector()
    for i in range(args.drones):
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind((args.host, api_port(i)))
        s.setblocking(False)
        selector.register(s, selectors.EVENT_READ)
    datagrams = 0
    start = time.monotonic()
    deadline = start + args.seconds
    while (now := time.monotonic()) < deadline:
        for key, _ in selector.select(timeout=min(0.5, deadline - now)):
            while True:
                try:
                    key.fileobj.recv(65536)
                except BlockingIOError:
                    break
                datagrams += 1
    print(f"{datagrams} datagrams in {args.seconds:.0f} s ({datagrams / args.seconds:.0f}/s) on {args.drones} ports")


if __name__ == "__main__":
    main()
