"""Concurrent pilots against a live run's airspace API (docs/airspace-api.yaml): one
connection per drone, each sending its requests on an open-loop schedule, latency
percentiles and throughput (docs/performance.md, "Airspace API under load").

    python3 tests/bench/airspace_load.py --fleet RUN_FOLDER/fleet.json --rate 1 --seconds 20

Every drone of the fleet file (or the first --drones of it; the read mix may have more
readers than the fleet has drones) is one pilot with its own
keep-alive connection (`--close`: a new connection per request, as the Chicago example
pilot does). Pilot k's requests are due at `k/N/rate + i/rate` seconds after the start,
whatever happened to the earlier ones; latency runs from the due time to the last byte of
the answer, so an answer that holds up the next request on its connection is counted in
that request too (no coordinated omission). `--procs` spreads the pilots over that many
processes (one asyncio loop each), so that the client is not the bottleneck.

Mixes:
- `pilot` (default): what a pilot does around a zone, cycled per drone: `GET /zones` first,
  then entry request, poll `GET /events?since=<cursor>`, `GET /zones/<zone>`, poll, renew
  the lease, poll, `GET /leases/<id>`, poll, release, `GET /healthz`. Granted or denied
  depends on the drone's group; a denied drone reads its zone instead of renewing and
  releasing. Credentials come from the environment variable the fleet file names for each
  drone (`credentialEnv`, `SADESIM_CREDENTIAL_<GROUP>`), as a pilot gets them. These
  requests change the run's airspace log (they are logged as evidence).
- `read`: only reads (`/healthz`, `/zones`, `/zones/<zone>`, `/events` polling): the run's
  results must not change at all under it (tests/interop/test_airspace_api_fuzz.py).

Prints one JSON object (requests, errors, achieved rate, p50/p90/p99/max in ms, client CPU)
and exits 1 when any request failed or got an unexpected status. Sends only to the URL it
is given (a run on this machine) and stops by itself after --seconds plus a drain of at
most --drain seconds.
"""
import argparse
import asyncio
import json
import multiprocessing
import os
import pathlib
import resource
import sys
import time
import urllib.parse

PILOT_CYCLE = ("request", "events", "zone", "events", "renew", "events", "lease", "events", "release", "healthz")
READ_CYCLE = ("events", "zones", "events", "zone", "events", "healthz")


class Pilot:
    """One drone's client: its connection, its cursor in the event log, its lease."""

    def __init__(self, drone: dict, zone: str, token: str | None, host: str, port: int, keepalive: bool):
        self.drone = drone
        self.zone = urllib.parse.quote(zone, safe="")
        self.token = token
        self.host, self.port, self.keepalive = host, port, keepalive
        self.reader = self.writer = None
        self.cursor = 0
        self.lease: str | None = None

    async def send(self, method: str, path: str, body: bytes = b"", auth: bool = False) -> tuple[int, bytes]:
        if self.writer is None:
            self.reader, self.writer = await asyncio.open_connection(self.host, self.port)
        head = [f"{method} {path} HTTP/1.1", f"Host: {self.host}:{self.port}", f"Content-Length: {len(body)}"]
        if body:
            head.append("Content-Type: application/json")
        if auth and self.token:
            head.append(f"Authorization: Bearer {self.token}")
        if not self.keepalive:
            head.append("Connection: close")
        self.writer.write(("\r\n".join(head) + "\r\n\r\n").encode() + body)
        status_line = await self.reader.readline()
        if not status_line:
            raise ConnectionError("the service closed the connection")
        status = int(status_line.split()[1])
        length, close = 0, not self.keepalive
        while (line := await self.reader.readline()) not in (b"\r\n", b""):
            name, _, value = line.decode("latin-1").partition(":")
            name = name.strip().lower()
            if name == "content-length":
                length = int(value)
            elif name == "connection" and value.strip().lower() == "close":
                close = True
        data = await self.reader.readexactly(length)
        if close:
            await self.close()
        return status, data

    async def close(self):
        if self.writer is not None:
            self.writer.close()
            try:
                await self.writer.wait_closed()
            except OSError:
                pass
        self.reader = self.writer = None

    async def step(self, what: str) -> str | None:
        """One request of the mix; returns a problem, or None when the answer is as expected."""
        if what == "zones":
            status, _ = await self.send("GET", "/zones")
        elif what == "zone" or (what in ("renew", "lease", "release") and self.lease is None):
            status, _ = await self.send("GET", f"/zones/{self.zone}")
        elif what == "events":
            status, data = await self.send("GET", f"/events?since={self.cursor}&limit=100")
            if status == 200:
                self.cursor = json.loads(data)["next"]
        elif what == "healthz":
            status, _ = await self.send("GET", "/healthz")
        elif what == "request":
            band = {"minAglM": 107.0, "maxAglM": 121.0}
            body = json.dumps({"drone": self.drone["name"], "operator": self.drone["operator"], "altitude": band})
            status, data = await self.send("POST", f"/zones/{self.zone}/requests", body.encode(), auth=True)
            if status == 200:
                verdict = json.loads(data)
                self.lease = verdict["lease"]["id"] if verdict["verdict"] == "granted" else None
        elif what == "renew":
            status, _ = await self.send("POST", f"/leases/{self.lease}/renew", auth=True)
        elif what == "lease":
            status, _ = await self.send("GET", f"/leases/{self.lease}")
        elif what == "release":
            status, _ = await self.send("DELETE", f"/leases/{self.lease}", auth=True)
            self.lease = None
        else:
            raise ValueError(what)
        return None if status == 200 else f"{what}: HTTP {status}"


async def fly(pilots: list[tuple[int, Pilot]], total: int, rate: float, seconds: float, drain: float,
              cycle: tuple) -> dict:
    latencies: list[float] = []
    errors: list[str] = []
    start = time.perf_counter() + 0.5  # every pilot is set up before the first is due
    stop_at = start + seconds + drain

    async def one(k: int, pilot: Pilot):
        phase = k / total / rate
        i = 0
        steps = ("zones",) + cycle * int(seconds * rate + 2)
        while True:
            due = start + phase + i / rate
            if due >= start + seconds:
                break
            wait = due - time.perf_counter()
            if wait > 0:
                await asyncio.sleep(wait)
            if time.perf_counter() > stop_at:
                errors.append("not sent before the drain ended")
                break
            try:
                problem = await asyncio.wait_for(pilot.step(steps[i]), timeout=max(0.1, stop_at - time.perf_counter()))
            except (OSError, asyncio.IncompleteReadError, asyncio.TimeoutError, ValueError, KeyError) as e:
                problem = f"{steps[i]}: {type(e).__name__}: {e}"
                await pilot.close()
            latencies.append(time.perf_counter() - due)
            if problem:
                errors.append(problem)
            i += 1
        await pilot.close()

    await asyncio.gather(*(one(k, p) for k, p in pilots))
    return {"latencies": latencies, "errors": errors, "wall": time.perf_counter() - start}


def worker(args: tuple) -> dict:
    chunk, total, rate, seconds, drain, cycle, url, keepalive = args
    parsed = urllib.parse.urlsplit(url)
    pilots = [(k, Pilot(d, zone, token, parsed.hostname, parsed.port or 80, keepalive)) for k, d, zone, token in chunk]
    cpu0 = time.process_time()
    result = asyncio.run(fly(pilots, total, rate, seconds, drain, cycle))
    result["cpu"] = time.process_time() - cpu0
    return result


def percentile(sorted_values: list[float], q: float) -> float:
    if not sorted_values:
        return float("nan")
    return sorted_values[min(len(sorted_values) - 1, int(q * len(sorted_values)))]


def load(fleet: dict, drones: int, rate: float, seconds: float, mix: str = "pilot", procs: int = 1,
         keepalive: bool = True, drain: float = 10.0, url: str | None = None) -> dict:
    """Runs the load and returns its figures (also the entry point for tests)."""
    url = url or fleet["airspaceUrl"]
    zones = [z.get("id") or z["properties"]["name"] for z in fleet.get("zones", {}).get("features", [])]
    if not zones:
        raise SystemExit("the fleet file has no zone: the load asks for one")
    if mix == "read":  # readers need no drone of their own: more of them than drones is fine
        chosen = [fleet["drones"][k % len(fleet["drones"])] for k in range(drones)]
    else:
        chosen = fleet["drones"][:drones]
        if len(chosen) < drones:
            raise SystemExit(f"the fleet has {len(chosen)} drones, fewer than --drones {drones} (the pilot mix "
                             "asks for entry as each drone)")
    missing = sorted({d["credentialEnv"] for d in chosen if d.get("credentialEnv") and d["credentialEnv"] not in os.environ})
    if mix == "pilot" and missing:
        raise SystemExit(f"set the drones' credentials in the environment first: {', '.join(missing)}")
    plan = [(k, d, zones[k % len(zones)], os.environ.get(d.get("credentialEnv") or "", None)) for k, d in enumerate(chosen)]
    cycle = PILOT_CYCLE if mix == "pilot" else READ_CYCLE
    jobs = [(plan[p::procs], len(plan), rate, seconds, drain, cycle, url, keepalive) for p in range(procs)]
    if procs == 1:
        results = [worker(jobs[0])]
    else:
        with multiprocessing.get_context("fork").Pool(procs) as pool:
            results = pool.map(worker, jobs)
    latencies = sorted(x for r in results for x in r["latencies"])
    errors = [e for r in results for e in r["errors"]]
    wall = max(r["wall"] for r in results)
    ms = lambda s: round(s * 1000, 3)  # noqa: E731
    return {
        "url": url, "mix": mix, "drones": len(plan), "ratePerDroneHz": rate, "targetPerS": len(plan) * rate,
        "seconds": seconds, "keepalive": keepalive, "procs": procs,
        "requests": len(latencies), "errors": len(errors), "errorSamples": sorted(set(errors))[:5],
        "achievedPerS": round(len(latencies) / wall, 1),
        "p50Ms": ms(percentile(latencies, 0.50)), "p90Ms": ms(percentile(latencies, 0.90)),
        "p99Ms": ms(percentile(latencies, 0.99)), "maxMs": ms(latencies[-1]) if latencies else None,
        "clientCpuS": round(sum(r["cpu"] for r in results), 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fleet", required=True, type=pathlib.Path, help="the run's fleet.json")
    parser.add_argument("--url", help="the airspace API (default: the fleet file's airspaceUrl)")
    parser.add_argument("--drones", type=int, help="pilots (default: every drone of the fleet)")
    parser.add_argument("--rate", type=float, default=1.0, help="requests per second per pilot (default 1)")
    parser.add_argument("--seconds", type=float, default=20.0, help="seconds of load (default 20)")
    parser.add_argument("--mix", choices=("pilot", "read"), default="pilot")
    parser.add_argument("--procs", type=int, default=1, help="client processes (default 1)")
    parser.add_argument("--close", action="store_true", help="a new connection per request")
    parser.add_argument("--drain", type=float, default=10.0, help="most seconds to wait for late answers")
    args = parser.parse_args()
    fleet = json.loads(args.fleet.read_text())
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    result = load(fleet, args.drones or len(fleet["drones"]), args.rate, args.seconds, args.mix, args.procs,
                  not args.close, args.drain, args.url)
    print(json.dumps(result))
    sys.exit(1 if result["errors"] else 0)


if __name__ == "__main__":
    main()
