#!/usr/bin/env python3
"""What the coordinator's lockstep costs: the window barrier and the snapshot merge, for
small shards as threads, as processes over loopback TCP, and as processes in their own
network namespaces over a bridge (as pods on different hosts talk).

    sudo python3 tests/bench/barrier.py --shards 2 8 32 100 --drones-per-shard 1
    sudo python3 tests/bench/barrier.py --shards 8 --drones-per-shard 125   # merge per drone

For each shard count it plans one scenario (drones hovering over an empty
100 m world: one flying drone per shard is a few microseconds a window, so the window's cost is
the lockstep's),
runs it three ways, each for `--seconds` and for `--short` simulated seconds, and prints
from the difference (start-up and world building cancel), per sync window (10 ms of simulated time):
- the wall time (µs): what the lockstep allows at most, windows per second;
- the coordinator's CPU time (µs; processes only, from wait4's rusage): the part of the
  window only one core can do, receiving and decoding every shard's snapshots, merging,
  recording, sending the next Advance.

The processes are `sim-worker coordinator` and one `sim-worker shard` per shard, exactly as
on Kubernetes (docs/kubernetes.md); the namespaces are the interop tests' (test_distributed.py).
Needs root for `ip netns`; with `--no-netns` only threads and loopback run. Results go in
docs/performance.md ("The lockstep across shards").
"""
import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

import yaml

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "interop"))
import test_distributed as net  # noqa: E402  (the interop tests' namespaces and addresses)

SECONDS = 16
PHYSICS_HZ = 1000
WINDOW_STEPS = 10


def scenario(shards: int, per_shard: int, seconds: int) -> dict:
    centre = {"latitudeDeg": 41.8796, "longitudeDeg": -87.6237}
    return {
        "apiVersion": "sadesim.io/v1alpha1",
        "kind": "SimulationRun",
        "metadata": {"name": f"barrier-{shards}x{per_shard}"},
        "spec": {
            "origin": {**centre, "altitudeMslM": 181},
            "duration": f"{seconds}s",
            "clock": {"mode": "asFastAsPossible"},
            "seed": 1,
            "sharding": {"dronesPerShard": per_shard},
            # Only the lockstep's own files: no recording.mcap, no ULogs.
            "recording": {"mcap": False, "ulog": False},
            "world": {"extentM": 100, "city": {"builtFraction": 0}},
            "fleet": [
                {
                    "name": "hover",
                    "count": shards * per_shard,
                    "airframe": "x500",
                    "operator": "bench",
                    "homes": {"randomInArea": {"center": centre, "radiusM": 80}},
                    "altitude": {"maxAglM": 60},
                    "mission": {"items": [{"takeoff": {"altitudeAglM": 10}}, {"loiter": {"holdS": 3600}}]},
                }
            ],
        },
    }


def plan(sadesim: str, doc: dict, folder: pathlib.Path) -> tuple[pathlib.Path, pathlib.Path]:
    folder.mkdir(parents=True, exist_ok=True)
    scenario_file = folder / "scenario.yaml"
    scenario_file.write_text(yaml.safe_dump(doc, sort_keys=False))
    planned = subprocess.run([sadesim, "plan", str(scenario_file), "--json"], capture_output=True, text=True)
    if planned.returncode != 0:
        raise SystemExit(f"sadesim plan refused the scenario:\n{planned.stdout}{planned.stderr}")
    plan_file = folder / "plan.json"
    plan_file.write_text(planned.stdout)
    return scenario_file, plan_file


def summary(out: pathlib.Path) -> dict:
    found = sorted(out.rglob("summary.json"))
    if not found:
        raise SystemExit(f"no summary.json under {out}")
    return json.loads(found[-1].read_text())


def run_threads(sadesim: str, scenario_file: pathlib.Path, out: pathlib.Path) -> dict:
    subprocess.run([sadesim, "run", str(scenario_file), "--out", str(out), "-q", "--no-mavlink"],
                   check=True, stdout=subprocess.DEVNULL)
    return {"wall_s": summary(out)["wallTimeS"], "coordinator_cpu_s": None}


def run_processes(sim_worker: str, plan_file: pathlib.Path, out: pathlib.Path, shards: int,
                  network: "net.Network | None") -> dict:
    """The coordinator and the shards as processes, in `network`'s namespaces or (None) on
    127.0.0.1; the coordinator's CPU time from its rusage."""
    def in_ns(ns: str | None, command: list[str]) -> list[str]:
        return ["ip", "netns", "exec", ns, *command] if ns else command

    host = net.COORDINATOR_IP if network else "127.0.0.1"
    port = 7400 if network else 7411
    coordinator = subprocess.Popen(
        in_ns(network.coordinator if network else None,
              [sim_worker, "coordinator", "--plan", str(plan_file), "--listen", f"{host}:{port}",
               "--out", str(out), "--airspace-bind", f"{host}:0", "--connect-timeout", "120"]),
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    # The coordinator says where it listens (a JSON line) before the shards may connect.
    for line in coordinator.stdout:
        if json.loads(line).get("type") == "listening":
            break
    else:
        raise SystemExit("the coordinator ended without listening")
    workers = [
        subprocess.Popen(
            in_ns(network.shards[i] if network else None,
                  [sim_worker, "shard", "--plan", str(plan_file), "--shard", str(i),
                   "--coordinator", f"{host}:{port}", "--no-mavlink"]),
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for i in range(shards)
    ]
    for _ in coordinator.stdout:  # its progress lines, until it exits
        pass
    _, status, usage = os.wait4(coordinator.pid, 0)
    coordinator.returncode = os.waitstatus_to_exitcode(status)
    for w in workers:
        w.wait(timeout=60)
    if coordinator.returncode != 0:
        raise SystemExit(f"the coordinator exited with {coordinator.returncode}")
    return {"wall_s": summary(out)["wallTimeS"], "coordinator_cpu_s": usage.ru_utime + usage.ru_stime}


def make_network(shards: int) -> "net.Network":
    net.remove_stale_namespaces()
    network = net.Network(shards)
    for name in network.names():
        net.ip("netns", "add", name)
        network.created.append(name)
    network.create()
    return network


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--shards", type=int, nargs="+", default=[2, 8, 32, 100])
    parser.add_argument("--drones-per-shard", type=int, default=1)
    parser.add_argument("--seconds", type=int, default=SECONDS)
    parser.add_argument("--short", type=int, default=6, help="the shorter run subtracted (s)")
    parser.add_argument("--no-netns", action="store_true", help="threads and loopback only")
    parser.add_argument("--bin", default=str(ROOT / "target" / "release"), help="folder of sadesim and sim-worker")
    args = parser.parse_args()
    sadesim, sim_worker = str(pathlib.Path(args.bin) / "sadesim"), str(pathlib.Path(args.bin) / "sim-worker")
    if args.short >= args.seconds:
        parser.error("--short must be shorter than --seconds")
    windows = (args.seconds - args.short) * PHYSICS_HZ // WINDOW_STEPS
    print(f"{windows} windows of {WINDOW_STEPS} steps, {os.cpu_count()} cores; per window:")
    print("shards  drones  threads wall µs  loopback wall µs  coordinator CPU µs  netns wall µs  coordinator CPU µs")
    for shards in args.shards:
        folder = pathlib.Path(tempfile.mkdtemp(prefix=f"barrier-{shards}-"))
        network = None
        try:
            if not args.no_netns:
                network = make_network(shards)
            # Each way runs twice, `--seconds` and `--short` long: the difference is the
            # windows alone (start-up, world building, connecting and the end cancel).
            results = {}
            for seconds in (args.short, args.seconds):
                scenario_file, plan_file = plan(
                    sadesim, scenario(shards, args.drones_per_shard, seconds), folder / f"{seconds}s")
                results[seconds] = {
                    "threads": run_threads(sadesim, scenario_file, folder / f"{seconds}s" / "threads"),
                    "loopback": run_processes(sim_worker, plan_file, folder / f"{seconds}s" / "loopback", shards, None),
                    "netns": network and run_processes(
                        sim_worker, plan_file, folder / f"{seconds}s" / "netns", shards, network),
                }

            def us(way: str, key: str) -> str:
                long, short = results[args.seconds][way], results[args.short][way]
                if not long or long[key] is None:
                    return "-"
                return f"{(long[key] - short[key]) / windows * 1e6:.0f}"

            print(f"{shards:6d}  {shards * args.drones_per_shard:6d}  {us('threads', 'wall_s'):>15}  "
                  f"{us('loopback', 'wall_s'):>16}  {us('loopback', 'coordinator_cpu_s'):>18}  "
                  f"{us('netns', 'wall_s'):>13}  {us('netns', 'coordinator_cpu_s'):>18}", flush=True)
        finally:
            if network:
                network.destroy()
            shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
