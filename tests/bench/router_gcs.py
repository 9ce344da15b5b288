"""The MAVLink router under many ground stations: N UDP ground stations on one run's router
(127.0.0.1:14550), each receiving the fleet's telemetry and sending a heartbeat and a
command every second, while ground station 0 sends timestamped probes that the router
passes to every other ground station (docs/performance.md, "MAVLink router with many
ground stations").

    .venv/bin/python tests/bench/router_gcs.py --sadesim target/release/sadesim --gcs 0 1 10 50 200

For each N, one real-time run of the quickstart's mission (`--drones` scripted drones,
`--seconds` of simulated time, MAVLink on, no pilot) flown by `sadesim run`, and then:
- **probe latency**: ground station 0 sends a DEBUG_VECT named `sdsprobe` carrying its send
  time 20 times a second; every other ground station looks for it in what it receives.
  One-way latency through the router (its GCS thread, the fan-out to the other ground
  stations), measured with one clock in this process; p50, p99, max, and the share of
  the expected deliveries (probes x other ground stations) that arrived, and the share
  among the ground stations the router serves (those that receive telemetry: at most 16
  UDP ones, the first to arrive; the router refuses the others while those stay live);
- **telemetry**: two observer ground stations (1 and 2) parse every frame and count the
  gaps in each drone's sequence numbers (frames lost between the drone and them); every
  ground station counts the bytes it receives (median and lowest per ground station);
- **command round trip**: the observers send MAV_CMD_REQUEST_MESSAGE (SYSTEM_TIME) to a
  drone twice a second and time the COMMAND_ACK (includes the drone's 20 ms MAVLink
  exchange period); every other ground station sends one a second without waiting;
- the run's CPU time (utime + stime of `sadesim`) per wall second, and its events.jsonl,
  compared with the run without ground stations (N = 0): the same bytes means the load
  changed nothing in the run's results.

Everything runs in this one Python process (a selector over all the sockets): at large N,
its own time to drain the sockets shows in the latencies. The router's ports are fixed
(14550/5760): no other run may use MAVLink on the machine meanwhile.
"""
import argparse
import hashlib
import json
import os
import pathlib
import random
import selectors
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time

os.environ["MAVLINK20"] = "1"
import yaml  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]
ROUTER = ("127.0.0.1", 14550)
PROBE_NAME = b"sdsprobe"
PROBES_PER_S = 20
OBSERVERS = (1, 2)
GCS_COMPONENT = 190
SYSTEM_TIME_ID = 2
REQUEST_MESSAGE = 512


def scenario(drones: int, seconds: int) -> dict:
    doc = yaml.safe_load((REPO / "examples" / "quickstart.yaml").read_text())
    doc["metadata"]["name"] = "router-gcs-bench"
    spec = doc["spec"]
    spec["clock"] = {"mode": "realtime"}
    spec["duration"] = f"{seconds}s"
    spec["fleet"][0]["count"] = drones
    return doc


class Gcs:
    """One UDP ground station: its socket, its encoder (own system id), what it saw."""

    def __init__(self, index: int):
        self.index = index
        self.sysid = 20 + index
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.mav = mavlink.MAVLink(None, srcSystem=self.sysid, srcComponent=GCS_COMPONENT)
        self.bytes = 0
        self.observer = index in OBSERVERS
        self.parser = mavlink.MAVLink(None) if self.observer else None
        if self.parser:
            self.parser.robust_parsing = True
        self.last_seq: dict[int, int] = {}
        self.frames = 0
        self.gaps = 0
        self.pending: dict[int, float] = {}  # drone -> send time of the command awaiting its ACK

    def send(self, msg):
        try:
            self.sock.sendto(msg.pack(self.mav), ROUTER)
        except (BlockingIOError, ConnectionRefusedError):
            pass

    def heartbeat(self):
        self.send(mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                                    mavlink.MAV_STATE_ACTIVE, 3))

    def command(self, drone: int):
        self.send(mavlink.MAVLink_command_long_message(drone, 1, REQUEST_MESSAGE, 0, SYSTEM_TIME_ID, 0, 0, 0, 0, 0, 0))


def percentile(values: list[float], p: float) -> float:
    if not values:
        return float("nan")
    values = sorted(values)
    return values[min(len(values) - 1, int(round(p / 100 * (len(values) - 1))))]


def cpu_s(pid: int) -> float:
    fields = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def fly(sadesim: str, doc: dict, gcs_count: int, warmup_s: float, work: pathlib.Path) -> dict:
    folder = work / f"gcs-{gcs_count}"
    folder.mkdir()
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    out = folder / "out"
    proc = subprocess.Popen([sadesim, "run", str(path), "--no-pilot", "--out", str(out), "-q"],
                            stdout=open(folder / "sadesim.log", "wb"), stderr=subprocess.STDOUT,
                            stdin=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not list(out.glob("*/*/fleet.json")):
            if proc.poll() is not None or time.monotonic() > deadline:
                raise SystemExit(f"sadesim ended or never wrote fleet.json: {(folder / 'sadesim.log').read_text()[-2000:]}")
            time.sleep(0.05)
        fleet = json.loads(next(out.glob("*/*/fleet.json")).read_text())
        drones = [d["systemId"] for d in fleet["drones"]]
        seconds = float(doc["spec"]["duration"].rstrip("s"))
        result = load(proc, drones, gcs_count, warmup_s, seconds - 3) if gcs_count else {"gcs": 0}
        code = proc.wait(timeout=600)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=30)
    run_dir = next(out.glob("*/*/"))
    summary = json.loads((run_dir / "summary.json").read_text())
    events = (run_dir / "events.jsonl").read_bytes()
    result.update(exit=code, endReason=summary.get("endReason"), rtf=summary.get("realTimeFactor"),
                  events_sha256=hashlib.sha256(events).hexdigest(), events_lines=events.count(b"\n"))
    return result


def load(proc: subprocess.Popen, drones: list[int], n: int, warmup_s: float, until_s: float) -> dict:
    """Runs `n` ground stations until `proc` ends; measures from `warmup_s` to `until_s` (s
    after the run's folder appeared: the run's sim time, on a real-time clock)."""
    stations = [Gcs(i) for i in range(n)]
    selector = selectors.DefaultSelector()
    for g in stations:
        selector.register(g.sock, selectors.EVENT_READ, g)
    rng = random.Random(1)
    start = time.monotonic()
    measure_from = start + warmup_s
    measure_until = start + until_s
    next_second = start
    next_probe = start
    next_observer_cmd = start
    probe_index = 0
    probes_sent = 0
    latencies_ms: list[float] = []
    probe_hits = 0
    rtts_ms: list[float] = []
    unanswered = 0
    cpu_at = last_cpu = None
    measuring = False
    bytes_at_measure: dict[int, int] = {}
    bytes_at_end: dict[int, int] = {}
    buf = bytearray(65536)
    while proc.poll() is None:
        now = time.monotonic()
        if measuring and now >= measure_until:
            measuring = False
            bytes_at_end = {g.index: g.bytes for g in stations}
            measure_from = float("inf")
        if not measuring and now >= measure_from:
            measuring = True
            cpu_at = (now, cpu_s(proc.pid))
            bytes_at_measure = {g.index: g.bytes for g in stations}
            for g in stations:
                g.frames = g.gaps = 0
        if now >= next_second:
            for g in stations:
                g.heartbeat()
                if not g.observer:
                    g.command(rng.choice(drones))
            next_second += 1.0
        if n > 1 and now >= next_probe:
            t_us = time.monotonic_ns() // 1000
            stations[0].send(mavlink.MAVLink_debug_vect_message(PROBE_NAME, t_us, float(probe_index), 0, 0))
            probe_index += 1
            if measuring:
                probes_sent += 1
            next_probe += 1.0 / PROBES_PER_S
        if now >= next_observer_cmd:
            for i in OBSERVERS:
                if i < n:
                    g = stations[i]
                    unanswered += len(g.pending) if measuring else 0
                    g.pending.clear()
                    drone = rng.choice(drones)
                    g.pending[drone] = time.monotonic()
                    g.command(drone)
            next_observer_cmd += 0.5
        timeout = max(0.0, min(next_second, next_probe if n > 1 else next_second, next_observer_cmd) - time.monotonic())
        for key, _ in selector.select(timeout=min(timeout, 0.05)):
            g = key.data
            while True:
                try:
                    size = g.sock.recv_into(buf)
                except (BlockingIOError, ConnectionRefusedError):
                    break
                received_us = time.monotonic_ns() // 1000
                data = bytes(buf[:size])
                g.bytes += size
                at = data.find(PROBE_NAME)
                while at >= 20:
                    (sent_us,) = struct.unpack_from("<Q", data, at - 20)
                    if measuring:
                        latencies_ms.append((received_us - sent_us) / 1000)
                        probe_hits += 1
                    at = data.find(PROBE_NAME, at + 1)
                if g.parser:
                    for msg in g.parser.parse_buffer(data) or []:
                        src = msg.get_srcSystem()
                        if src in drones:
                            seq = msg.get_seq()
                            last = g.last_seq.get(src)
                            if last is not None and measuring:
                                g.gaps += (seq - last - 1) % 256
                            g.last_seq[src] = seq
                            if measuring:
                                g.frames += 1
                            if msg.get_msgId() == mavlink.MAVLINK_MSG_ID_COMMAND_ACK and msg.target_system == g.sysid \
                                    and msg.command == REQUEST_MESSAGE and src in g.pending:
                                sent = g.pending.pop(src)
                                if measuring:
                                    rtts_ms.append((time.monotonic() - sent) * 1000)
        if measuring and proc.poll() is None:
            try:
                last_cpu = (time.monotonic(), cpu_s(proc.pid))
            except (FileNotFoundError, ProcessLookupError):
                pass
    window = last_cpu[0] - cpu_at[0]
    if not bytes_at_end:
        bytes_at_end = {g.index: g.bytes for g in stations}
    per_gcs = sorted((bytes_at_end[g.index] - bytes_at_measure.get(g.index, 0)) / window / 1000 for g in stations)
    frames = sum(g.frames for g in stations if g.observer)
    gaps = sum(g.gaps for g in stations if g.observer)
    expected = probes_sent * (n - 1)
    # Ground stations the router serves (at most 16 UDP ones; the others are refused).
    served = [b for b in per_gcs if b >= 0.5]
    expected_served = probes_sent * (len(served) - 1)
    return {
        "gcs": n,
        "window_s": round(window, 1),
        "probe_p50_ms": round(percentile(latencies_ms, 50), 2),
        "probe_p99_ms": round(percentile(latencies_ms, 99), 2),
        "probe_max_ms": round(max(latencies_ms), 2) if latencies_ms else None,
        "probe_delivered": round(probe_hits / expected, 4) if expected else None,
        "telemetry_lost": round(gaps / (frames + gaps), 5) if frames + gaps else None,
        "kB_per_s_median_gcs": round(percentile(per_gcs, 50), 1),
        "kB_per_s_lowest_gcs": round(per_gcs[0], 1) if per_gcs else None,
        "gcs_without_telemetry": sum(1 for b in per_gcs if b < 0.5),
        "gcs_served": len(served),
        "probe_delivered_to_served": round(probe_hits / expected_served, 4) if expected_served > 0 else None,
        "kB_per_s_median_served": round(percentile(served, 50), 1) if served else None,
        "kB_per_s_lowest_served": round(served[0], 1) if served else None,
        "cmd_rtt_p50_ms": round(percentile(rtts_ms, 50), 1),
        "cmd_rtt_p99_ms": round(percentile(rtts_ms, 99), 1),
        "cmd_unanswered": unanswered,
        "sadesim_cpu": round((last_cpu[1] - cpu_at[1]) / window, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sadesim", default=str(REPO / "target" / "release" / "sadesim"))
    parser.add_argument("--gcs", type=int, nargs="+", default=[0, 1, 10, 50, 200])
    parser.add_argument("--drones", type=int, default=8)
    parser.add_argument("--seconds", type=int, default=45, help="simulated (= wall) seconds per run")
    parser.add_argument("--warmup", type=float, default=8.0, help="seconds of load before measuring")
    parser.add_argument("--json", type=pathlib.Path, help="also write the results here")
    args = parser.parse_args()
    doc = scenario(args.drones, args.seconds)
    work = pathlib.Path(tempfile.mkdtemp(prefix="router-gcs-bench-"))
    results = []
    try:
        for n in args.gcs:
            r = fly(args.sadesim, doc, n, args.warmup, work)
            results.append(r)
            print(json.dumps(r), flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    base = next((r for r in results if r["gcs"] == 0), None)
    if base:
        for r in results:
            r["events_same_as_without_gcs"] = r["events_sha256"] == base["events_sha256"]
        print("events.jsonl identical to the run without ground stations:",
              {r["gcs"]: r["events_same_as_without_gcs"] for r in results})
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))
    sys.exit(0 if not base or all(r["events_same_as_without_gcs"] for r in results) else 1)


if __name__ == "__main__":
    main()
