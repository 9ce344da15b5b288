#!/usr/bin/env python3
"""Soak test: a long real-time run with memory and file handles sampled.

Flies a fleet of scripted drones (random waypoints over an open disc in Chicago, wind,
MAVLink endpoints and routers on, recording.mcap and the ULogs written) with the real-time
clock for `--minutes`, while this script samples the `sadesim run` process every
`--interval` seconds from /proc: resident memory (VmRSS), open file descriptors and
threads. A ground station (a UDP socket sending heartbeats to every drone's router
segment and reading the telemetry back) keeps the MAVLink path busy the whole time.

After a warm-up (from the moment the run folder's fleet.json appears, i.e. the world is
built and the flight starts: the first `--warmup` fraction of the flight, at least 30 s,
while the fleet takes off and buffers reach their working size) to 10 s (or three sample
intervals) before the end of the flight (then the run writes its report and frees the
world), it fits a least-squares line to the memory samples and checks:

- memory: the fitted growth over the measured window stays under `--max-rss-growth-mib`
  (default: 2 MiB or 1 % of the median, whichever is larger);
- file descriptors: the count never exceeds the count at the end of the warm-up by more
  than `--max-fd-growth` (default 4);
- threads: the same, with `--max-thread-growth` (default 2);
- the run itself exits 0.

It writes `samples.csv` and `soak.json` (the figures) into `--out`, prints the figures and
exits 1 when a check fails. docs/performance.md ("Soak") gives the long command and its
results; tests/run.sh runs a short version.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import socket
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

SCENARIO = """\
apiVersion: sadesim.io/v1alpha1
kind: SimulationRun
metadata: {{name: soak}}
spec:
  origin: {{latitudeDeg: 41.8796, longitudeDeg: -87.6237, altitudeMslM: 181}}
  duration: {seconds}s
  clock: {{mode: realtime}}
  seed: 7
  environment:
    wind: {{speedMps: 5, directionFromDeg: 270, turbulence: light}}
  world:
    openAreas:
      - {{name: flight area, center: {{latitudeDeg: 41.8796, longitudeDeg: -87.6237}}, radiusM: 700}}
  fleet:
    - name: soak
      count: {drones}
      airframe: x500
      operator: soak
      homes: {{randomInArea: {{center: {{latitudeDeg: 41.8796, longitudeDeg: -87.6237}}, radiusM: 400}}}}
      altitude: {{maxAglM: 120}}
      mission:
        speedMps: 8
        items:
          - takeoff: {{altitudeAglM: 20}}
          - randomWaypoints:
              area: {{center: {{latitudeDeg: 41.8796, longitudeDeg: -87.6237}}, radiusM: 500}}
              count: 10000
              minAltitudeAglM: 20
              maxAltitudeAglM: 60
"""


def proc_sample(pid: int) -> dict[str, int] | None:
    """VmRSS (KiB), threads and open file descriptors of `pid`; None once it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        fds = len(os.listdir(f"/proc/{pid}/fd"))
    except (FileNotFoundError, ProcessLookupError):
        return None
    fields = {}
    for line in status.splitlines():
        key, _, value = line.partition(":")
        fields[key] = value.split()
    if "VmRSS" not in fields:  # a zombie: exited, not yet reaped
        return None
    return {"rss_kib": int(fields["VmRSS"][0]), "threads": int(fields["Threads"][0]), "fds": fds}


def least_squares_slope(xs: list[float], ys: list[float]) -> float:
    """The slope of the least-squares line through (xs, ys)."""
    mx, my = statistics.fmean(xs), statistics.fmean(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    if sxx == 0:
        return 0.0
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx


def ground_station(fleet_file: Path, stop: threading.Event, counts: dict[str, int]) -> None:
    """Sends a GCS heartbeat once a second to every router segment of `fleet.json` (its
    `gcsUrls`) and reads
    whatever comes back (telemetry), counting the datagrams."""
    deadline = time.monotonic() + 120
    while not fleet_file.exists():
        if stop.is_set() or time.monotonic() > deadline:
            return
        time.sleep(0.5)
    time.sleep(0.5)  # the runner writes fleet.json once; let it finish
    fleet = json.loads(fleet_file.read_text())
    # `udpout://HOST:PORT`: the router segment a ground station sends to and hears from.
    ports = sorted({int(url.rsplit(":", 1)[1]) for url in fleet.get("gcsUrls", [])})
    counts["segments"] = len(ports)
    counts["fleetAtS"] = time.monotonic()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(0.2)
    # MAVLink 2 HEARTBEAT from system 255 (a GCS), CRC_EXTRA 50, computed below.
    payload = bytes([0, 0, 0, 0, 6, 8, 0, 0, 3])  # custom_mode, type GCS, autopilot invalid, ...
    seq = 0
    next_beat = 0.0
    while not stop.is_set():
        now = time.monotonic()
        if now >= next_beat:
            for port in ports:
                sock.sendto(heartbeat_frame(seq, payload), ("127.0.0.1", port))
                seq = (seq + 1) % 256
            next_beat = now + 1.0
        try:
            while True:
                sock.recvfrom(65536)
                counts["received"] = counts.get("received", 0) + 1
        except (TimeoutError, socket.timeout):
            pass
        except OSError:
            time.sleep(0.2)
    sock.close()


def x25(data: bytes, crc: int = 0xFFFF) -> int:
    for b in data:
        tmp = b ^ (crc & 0xFF)
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
    return crc


def heartbeat_frame(seq: int, payload: bytes) -> bytes:
    header = bytes([0xFD, len(payload), 0, 0, seq, 255, 190, 0, 0, 0])
    crc = x25(header[1:] + payload)
    crc = x25(bytes([50]), crc)
    return header + payload + crc.to_bytes(2, "little")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sadesim", default="target/release/sadesim", help="the sadesim binary")
    ap.add_argument("--minutes", type=float, default=60.0, help="simulated (= wall) minutes")
    ap.add_argument("--drones", type=int, default=64)
    ap.add_argument("--interval", type=float, default=5.0, help="seconds between samples")
    ap.add_argument("--warmup", type=float, default=0.2, help="fraction of the run not judged")
    ap.add_argument("--max-rss-growth-mib", type=float, default=None)
    ap.add_argument("--max-fd-growth", type=int, default=4)
    ap.add_argument("--max-thread-growth", type=int, default=2)
    ap.add_argument("--out", type=Path, required=True, help="folder for the run, samples.csv, soak.json")
    args = ap.parse_args()

    args.out.mkdir(parents=True, exist_ok=True)
    seconds = int(args.minutes * 60)
    scenario = args.out / "soak.yaml"
    scenario.write_text(SCENARIO.format(seconds=seconds, drones=args.drones))
    runs = args.out / "runs"
    log = (args.out / "sadesim.log").open("w")
    start = time.monotonic()
    proc = subprocess.Popen([args.sadesim, "run", str(scenario), "--out", str(runs), "-q"],
                            stdout=log, stderr=subprocess.STDOUT)
    stop = threading.Event()
    counts: dict[str, int] = {}

    def fleet_file() -> Path:
        found = sorted(runs.glob("soak/*/fleet.json"))
        return found[-1] if found else runs / "soak" / "none" / "fleet.json"

    gcs = threading.Thread(target=lambda: ground_station_when_ready(fleet_file, stop, counts), daemon=True)
    gcs.start()

    samples: list[dict[str, float]] = []
    with (args.out / "samples.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["t_s", "rss_kib", "fds", "threads"])
        while proc.poll() is None:
            s = proc_sample(proc.pid)
            if s is not None:
                t = time.monotonic() - start
                samples.append({"t": t, **s})
                writer.writerow([f"{t:.1f}", s["rss_kib"], s["fds"], s["threads"]])
                f.flush()
            time.sleep(args.interval)
    stop.set()
    wall = time.monotonic() - start
    code = proc.returncode

    # The warm-up counts from the start of the flight (fleet.json written: the world is
    # built), not from the process start, whose world build time varies with the machine.
    flying_from = counts["fleetAtS"] - start if "fleetAtS" in counts else 0.0
    warm_end = flying_from + max(30.0, args.warmup * (wall - flying_from))
    # The judged window ends before the flight does: afterwards the run writes its report
    # and frees the world, and its memory falls (fleet.json is seen a little after the
    # flight starts, hence the margin).
    flight_end = flying_from + seconds - max(10.0, 3 * args.interval)
    judged = [s for s in samples if warm_end <= s["t"] <= flight_end]
    failures = []
    result: dict[str, object] = {"exitCode": code, "wallS": round(wall, 1), "drones": args.drones,
                                 "minutes": args.minutes, "samples": len(samples), "judged": len(judged),
                                 "flyingFromS": round(flying_from, 1),
                                 "gcsDatagramsReceived": counts.get("received", 0)}
    if code != 0:
        failures.append(f"the run exited {code} (see {args.out / 'sadesim.log'})")
    if len(judged) < 3:
        failures.append(f"only {len(judged)} samples after the warm-up: run longer or sample more often")
    else:
        ts = [s["t"] for s in judged]
        rss_mib = [s["rss_kib"] / 1024 for s in judged]
        slope = least_squares_slope(ts, rss_mib)
        window = ts[-1] - ts[0]
        growth = slope * window
        median = statistics.median(rss_mib)
        limit = args.max_rss_growth_mib if args.max_rss_growth_mib is not None else max(2.0, 0.01 * median)
        base_fds, base_threads = judged[0]["fds"], judged[0]["threads"]
        max_fds, max_threads = max(s["fds"] for s in judged), max(s["threads"] for s in judged)
        result.update({
            "rssMedianMiB": round(median, 1), "rssMinMiB": round(min(rss_mib), 1),
            "rssMaxMiB": round(max(rss_mib), 1), "rssSlopeMiBPerHour": round(slope * 3600, 2),
            "rssGrowthMiB": round(growth, 2), "rssGrowthLimitMiB": round(limit, 2),
            "windowS": round(window, 1), "fdsAtWarmup": base_fds, "fdsMax": max_fds,
            "threadsAtWarmup": base_threads, "threadsMax": max_threads,
        })
        if growth > limit:
            failures.append(f"resident memory grew {growth:.1f} MiB over {window:.0f} s "
                            f"({slope * 3600:.1f} MiB/h; limit {limit:.1f} MiB)")
        if max_fds > base_fds + args.max_fd_growth:
            failures.append(f"open file descriptors rose from {base_fds} to {max_fds} "
                            f"(limit +{args.max_fd_growth})")
        if max_threads > base_threads + args.max_thread_growth:
            failures.append(f"threads rose from {base_threads} to {max_threads} "
                            f"(limit +{args.max_thread_growth})")
    result["failures"] = failures
    (args.out / "soak.json").write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    if failures:
        for f in failures:
            print(f"soak: FAILED: {f}", file=sys.stderr)
        return 1
    print("soak: memory, file descriptors and threads stayed flat")
    return 0


def ground_station_when_ready(fleet_file, stop: threading.Event, counts: dict[str, int]) -> None:
    """Waits for the run folder's fleet.json, then runs the ground station on it."""
    deadline = time.monotonic() + 300
    while not stop.is_set() and time.monotonic() < deadline:
        path = fleet_file()
        if path.exists():
            ground_station(path, stop, counts)
            return
        time.sleep(0.5)


if __name__ == "__main__":
    sys.exit(main())
