"""Distributed shards for real: `sim-worker coordinator` and one `sim-worker shard` per
shard, each in its own network namespace, talking TCP over a bridge as pods on different
hosts would.

    switch namespace:  br0 --+-- veth --> coordinator namespace  10.77.0.1
                             +-- veth --> shard 0 namespace      10.77.0.2
                             +-- veth --> shard 1 namespace      10.77.0.3
                             +-- veth --> shard 2 namespace      10.77.0.4

Checked here:
- a run across namespaces records the same trajectory.csv and events.jsonl, byte for byte,
  as `sadesim run` in one process;
- `kill -9` of a shard fails the run promptly: the coordinator exits non-zero with a
  `failed` line naming the shard and its address, still writes its files (events end with
  `runEnded`, summary.json's endReason names the shard, recordings closed), the other
  shards exit, and the run folder with every process's log archives and verifies;
- a shard that stops answering (SIGSTOP: a host gone without a FIN) fails the run after
  `--shard-timeout`;
- a shard given a wrong coordinator address fails within `--connect-timeout`, naming it;
- the `sadesim.io/stop` annotation (a downward-API file, `--control-file`) ends a running
  run with its reason, as the operator does when the pilot Job ends.

Needs root (or CAP_NET_ADMIN/CAP_SYS_ADMIN) for `ip netns`; skipped with the reason where
the machine refuses namespaces. Namespaces are named `sdsim-<pid>-...`; ones left by an
earlier crashed session (whose pid is gone) are removed first. Every wait is bounded: a
hang fails the test instead of blocking CI.
"""
import json
import os
import pathlib
import queue
import re
import shutil
import signal
import subprocess
import threading
import time
import warnings

import pytest
import yaml

from simrun import wait_until

PREFIX = "sdsim"
SHARDS = 3
DRONES_PER_SHARD = 2
COORDINATOR_IP = "10.77.0.1"
COORDINATOR_PORT = 7400
AIRSPACE_PORT = 8480


def shard_ip(index: int) -> str:
    return f"10.77.0.{index + 2}"


# -- network namespaces -------------------------------------------------------------------


def ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30, check=check)


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def delete_namespace(name: str):
    """Kills what still runs in `name` (processes a test session started there) and deletes it."""
    pids = ip("netns", "pids", name, check=False).stdout.split()
    for pid in pids:
        try:
            os.kill(int(pid), signal.SIGKILL)
        except (ProcessLookupError, ValueError):
            pass
    ip("netns", "del", name, check=False)


def remove_stale_namespaces():
    """Namespaces of earlier sessions of this test whose pytest process is gone."""
    listing = ip("netns", "list", check=False).stdout
    for line in listing.splitlines():
        m = re.match(rf"^({PREFIX}-(\d+)-\S+)", line)
        if m and int(m.group(2)) != os.getpid() and not pid_alive(int(m.group(2))):
            delete_namespace(m.group(1))


class Network:
    """The switch, coordinator and shard namespaces, wired to one bridge on 10.77.0.0/24."""

    def __init__(self, shards: int):
        tag = f"{PREFIX}-{os.getpid()}"
        self.switch = f"{tag}-sw"
        self.coordinator = f"{tag}-co"
        self.shards = [f"{tag}-s{i}" for i in range(shards)]
        self.created: list[str] = []

    def names(self) -> list[str]:
        return [self.switch, self.coordinator, *self.shards]

    def create(self):
        # The switch namespace holds the bridge, so nothing is added to the host's network.
        ip("-n", self.switch, "link", "add", "br0", "type", "bridge")
        ip("-n", self.switch, "link", "set", "br0", "up")
        hosts = [(self.coordinator, COORDINATOR_IP)] + [(ns, shard_ip(i)) for i, ns in enumerate(self.shards)]
        for n, (ns, address) in enumerate(hosts):
            port = f"p{n}"
            ip("-n", self.switch, "link", "add", port, "type", "veth", "peer", "name", "eth0", "netns", ns)
            ip("-n", self.switch, "link", "set", port, "master", "br0", "up")
            ip("-n", ns, "addr", "add", f"{address}/24", "dev", "eth0")
            ip("-n", ns, "link", "set", "eth0", "up")
            ip("-n", ns, "link", "set", "lo", "up")

    def destroy(self):
        for name in reversed(self.created):
            delete_namespace(name)
        self.created.clear()


@pytest.fixture(scope="module")
def network():
    remove_stale_namespaces()
    net = Network(SHARDS)
    try:
        for name in net.names():
            try:
                ip("netns", "add", name)
            except (subprocess.CalledProcessError, FileNotFoundError, PermissionError) as e:
                reason = getattr(e, "stderr", None) or str(e)
                reason = f"network namespaces unavailable: `ip netns add {name}` failed: {reason.strip()}"
                # Also as a warning: `pytest -q` lists warnings, not skip reasons.
                warnings.warn(reason, stacklevel=1)
                pytest.skip(reason)
            net.created.append(name)
        net.create()
        yield net
    finally:
        net.destroy()


# -- processes ----------------------------------------------------------------------------


def scenario(name: str, duration: str, clock: dict) -> dict:
    """Six scripted drones, two per shard, over Millennium Park: take off, fly 45 m north, land."""
    park = {"latitudeDeg": 41.8818, "longitudeDeg": -87.6226}
    return {
        "apiVersion": "sadesim.io/v1alpha1",
        "kind": "SimulationRun",
        "metadata": {"name": name},
        "spec": {
            "origin": {"latitudeDeg": 41.8796, "longitudeDeg": -87.6237, "altitudeMslM": 181},
            "duration": duration,
            "clock": clock,
            "seed": 7,
            "sharding": {"dronesPerShard": DRONES_PER_SHARD},
            "world": {"openAreas": [{"name": "park", "center": park, "radiusM": 250}]},
            "fleet": [
                {
                    "name": "swarm",
                    "count": SHARDS * DRONES_PER_SHARD,
                    "airframe": "x500",
                    "operator": "interop-tests",
                    "homes": {"randomInArea": {"name": "park", "center": park, "radiusM": 80}},
                    "altitude": {"maxAglM": 60},
                    "mission": {
                        "speedMps": 6,
                        "items": [
                            {"takeoff": {"altitudeAglM": 10}},
                            {"waypoint": {"latitudeDeg": 41.8822, "longitudeDeg": -87.6226, "altitudeAglM": 12}},
                            {"land": {}},
                        ],
                    },
                }
            ],
        },
    }


class Cluster:
    """A coordinator and its shards started in their namespaces for one plan. Every
    process's output is kept in `out/logs/`; `stop()` kills whatever is still running."""

    def __init__(self, sim_worker: str, net: Network, plan: pathlib.Path, out: pathlib.Path):
        self.sim_worker = sim_worker
        self.net = net
        self.plan = plan
        self.out = out
        self.logs = out / "logs"
        self.logs.mkdir(parents=True, exist_ok=True)
        self.coordinator: subprocess.Popen | None = None
        self.shards: list[subprocess.Popen] = []
        self.reports: "queue.Queue[dict]" = queue.Queue()
        self.report_lines: list[dict] = []
        self._files = []
        self._reader: threading.Thread | None = None

    def _log(self, name: str):
        f = open(self.logs / name, "wb")
        self._files.append(f)
        return f

    def start_coordinator(self, *extra: str):
        self.coordinator = subprocess.Popen(
            ["ip", "netns", "exec", self.net.coordinator, self.sim_worker, "coordinator",
             "--plan", str(self.plan), "--listen", f"{COORDINATOR_IP}:{COORDINATOR_PORT}",
             "--out", str(self.out), "--airspace-bind", f"{COORDINATOR_IP}:{AIRSPACE_PORT}", *extra],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=self._log("coordinator.log"),
            start_new_session=True,
        )
        stdout_copy = self._log("coordinator.stdout.jsonl")

        def read():
            for line in self.coordinator.stdout:
                stdout_copy.write(line)
                stdout_copy.flush()
                try:
                    self.reports.put(json.loads(line))
                except ValueError:
                    self.reports.put({"type": "unparsed", "line": line.decode(errors="replace")})
            self.reports.put({"type": "eof"})

        self._reader = threading.Thread(target=read, daemon=True)
        self._reader.start()
        listening = self.next_report(60, lambda r: r["type"] in ("listening", "failed", "eof"))
        assert listening["type"] == "listening", f"coordinator did not listen: {listening}\n{self.tail()}"
        assert listening["address"] == f"{COORDINATOR_IP}:{COORDINATOR_PORT}", listening

    def start_shards(self, *extra: str):
        for i, ns in enumerate(self.net.shards):
            log = self._log(f"shard-{i}.log")
            self.shards.append(
                subprocess.Popen(
                    ["ip", "netns", "exec", ns, self.sim_worker, "shard", "--plan", str(self.plan),
                     "--shard", str(i), "--coordinator", f"{COORDINATOR_IP}:{COORDINATOR_PORT}",
                     "--no-mavlink", *extra],
                    stdin=subprocess.DEVNULL,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    start_new_session=True,
                )
            )

    def next_report(self, timeout_s: float, want) -> dict:
        """The next coordinator stdout line for which `want(line)` holds (bounded wait)."""
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"timed out after {timeout_s:.0f} s waiting for a coordinator line\n{self.tail()}")
            try:
                r = self.reports.get(timeout=left)
            except queue.Empty:
                continue
            self.report_lines.append(r)
            if want(r) or r["type"] == "eof":
                return r

    def wait_all(self, timeout_s: float) -> dict[str, int]:
        """Exit codes of every process; fails naming the ones still running after `timeout_s`."""
        procs = {"coordinator": self.coordinator, **{f"shard {i}": p for i, p in enumerate(self.shards)}}
        deadline = time.monotonic() + timeout_s
        for p in procs.values():
            try:
                p.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
        running = [name for name, p in procs.items() if p.poll() is None]
        assert not running, f"still running {timeout_s:.0f} s later: {running}\n{self.tail()}"
        if self._reader is not None:
            self._reader.join(timeout=10)
        return {name: p.returncode for name, p in procs.items()}

    def tail(self, chars: int = 2000) -> str:
        parts = []
        for f in sorted(self.logs.glob("*")):
            text = f.read_text(errors="replace") if f.exists() else ""
            parts.append(f"--- {f.name} ---\n{text[-chars:]}")
        return "\n".join(parts)

    def stop(self):
        for p in [self.coordinator, *self.shards]:
            if p is not None and p.poll() is None:
                p.kill()
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    pass
        for f in self._files:
            f.close()


@pytest.fixture
def cluster(sim_worker, network):
    made = []

    def make(plan: pathlib.Path, out: pathlib.Path) -> Cluster:
        c = Cluster(sim_worker, network, plan, out)
        made.append(c)
        return c

    yield make
    for c in made:
        c.stop()


def write_plan(sadesim: str, doc: dict, folder: pathlib.Path) -> tuple[pathlib.Path, pathlib.Path]:
    """The scenario file and its RunPlan (`sadesim plan --json`) in `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    scenario_file = folder / f"{doc['metadata']['name']}.yaml"
    scenario_file.write_text(yaml.safe_dump(doc, sort_keys=False))
    planned = subprocess.run([sadesim, "plan", str(scenario_file), "--json"], capture_output=True, text=True, timeout=120)
    assert planned.returncode == 0, planned.stderr
    plan = folder / "plan.json"
    plan.write_text(planned.stdout)
    assert [s["index"] for s in json.loads(planned.stdout)["shards"]] == list(range(SHARDS))
    return scenario_file, plan


def events(path: pathlib.Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def assert_same_bytes(a: pathlib.Path, b: pathlib.Path):
    x, y = a.read_bytes(), b.read_bytes()
    if x != y:
        xl, yl = x.decode().splitlines(), y.decode().splitlines()
        n = next((i for i, (p, q) in enumerate(zip(xl, yl)) if p != q), min(len(xl), len(yl)))
        raise AssertionError(
            f"{a.name} differs at line {n + 1} ({len(xl)} vs {len(yl)} lines):\n"
            f"  in-process: {xl[n] if n < len(xl) else '<end>'}\n  distributed: {yl[n] if n < len(yl) else '<end>'}"
        )


def assert_recordings_closed(out: pathlib.Path, plan: dict):
    """MCAP and ULog files, when the plan records them, are complete files (MCAP: footer
    and closing magic, readable summary; ULog: header)."""
    from mcap.reader import make_reader

    recording = plan["spec"].get("recording") or {}
    if recording.get("mcap", True):
        mcap = out / "recording.mcap"
        data = mcap.read_bytes()
        assert data.endswith(b"\x89MCAP0\r\n"), f"{mcap} was not closed (no trailing magic)"
        with open(mcap, "rb") as f:
            assert make_reader(f).get_summary() is not None, f"{mcap} has no summary section"
    if recording.get("ulog", True):
        ulogs = sorted((out / "ulog").glob("*.ulg"))
        assert len(ulogs) == len(plan["drones"]), ulogs
        for u in ulogs:
            assert u.read_bytes()[:7] == b"ULog\x01\x12\x35", f"{u} has no ULog header"


# -- tests --------------------------------------------------------------------------------


def test_a_run_across_namespaces_matches_the_in_process_run(sadesim, cluster, tmp_path):
    doc = scenario("distributed", "40s", {"mode": "asFastAsPossible"})
    scenario_file, plan = write_plan(sadesim, doc, tmp_path)

    local_root = tmp_path / "local"
    local = subprocess.run(
        [sadesim, "run", str(scenario_file), "--no-mavlink", "--out", str(local_root), "-q"],
        capture_output=True, text=True, timeout=300,
    )
    assert local.returncode == 0, local.stdout + local.stderr
    (local_dir,) = (local_root / "distributed").glob("*/")
    # Same plan, so any difference below comes from the transport.
    assert json.loads((local_dir / "plan.json").read_text()) == json.loads(plan.read_text())

    out = tmp_path / "distributed"
    c = cluster(plan, out)
    c.start_coordinator()
    c.start_shards()
    finished = c.next_report(300, lambda r: r["type"] in ("finished", "failed"))
    assert finished["type"] == "finished", f"{finished}\n{c.tail()}"
    codes = c.wait_all(60)
    assert codes == {"coordinator": 0, **{f"shard {i}": 0 for i in range(SHARDS)}}, f"{codes}\n{c.tail()}"

    summary = json.loads((out / "summary.json").read_text())
    assert summary["endReason"] == "duration" and summary["simTimeS"] == 40.0, summary
    assert summary["shards"] == SHARDS and summary["drones"] == SHARDS * DRONES_PER_SHARD
    assert all(d["tookOff"] and d["landed"] and not d["crashed"] for d in summary["perDrone"]), summary["perDrone"]
    assert finished["summary"] == summary
    # Byte-identical: the shard protocol carries every float exactly, whatever the carrier.
    assert_same_bytes(local_dir / "trajectory.csv", out / "trajectory.csv")
    assert_same_bytes(local_dir / "events.jsonl", out / "events.jsonl")
    local_summary = json.loads((local_dir / "summary.json").read_text())
    # Wall-clock and CPU-time fields differ legitimately; everything simulated is the same.
    for measured in ("wallTimeS", "realTimeFactor", "recordingCpuS"):
        local_summary.pop(measured), summary.pop(measured)
    # What each shard spent stepping its drones: in summary.json for in-process shards,
    # in each shard process's own log for remote ones.
    assert len(local_summary.pop("shardCpuS")) == SHARDS and "shardCpuS" not in summary, summary
    assert summary == local_summary
    for i in range(SHARDS):
        shard_log = (out / "logs" / f"shard-{i}.log").read_text()
        assert f"shard {i}: stepped {DRONES_PER_SHARD} drones in " in shard_log, shard_log
    # The shards really were remote: each connected from its own namespace's address.
    log = (out / "logs" / "coordinator.log").read_text()
    for i in range(SHARDS):
        assert f"shard {i} connected from {shard_ip(i)}:" in log, log


def test_killing_a_shard_fails_the_run_with_the_reason_and_keeps_the_evidence(sadesim, cluster, tmp_path):
    # Paced (4x real time) and long, so the run is surely still going when the shard dies.
    doc = scenario("shard-killed", "10m", {"mode": "scaled", "factor": 4})
    _, plan = write_plan(sadesim, doc, tmp_path)
    out = tmp_path / "run" / "shard-killed" / "attempt"
    c = cluster(plan, out)
    c.start_coordinator()
    c.start_shards()
    progress = c.next_report(120, lambda r: r["type"] in ("failed", "finished") or (r["type"] == "progress" and r["simTimeS"] >= 5))
    assert progress["type"] == "progress", f"{progress}\n{c.tail()}"

    victim = c.shards[1]
    # `ip netns exec` execs the command: the process is the shard itself.
    assert pathlib.Path(f"/proc/{victim.pid}/comm").read_text().strip() == "sim-worker"
    os.kill(victim.pid, signal.SIGKILL)

    failed = c.next_report(60, lambda r: r["type"] in ("failed", "finished"))
    codes = c.wait_all(60)  # every process is gone, the survivors included
    assert failed["type"] == "failed", f"{failed}\n{c.tail()}"
    assert failed["role"] == "shard" and failed["shard"] == 1, failed
    assert failed["address"].startswith(f"{shard_ip(1)}:"), failed
    assert failed["reason"].startswith(f"shard 1 ({shard_ip(1)}:"), failed
    assert "connection closed" in failed["reason"], failed
    assert codes["coordinator"] != 0, codes
    assert codes["shard 1"] == -signal.SIGKILL, codes
    # The survivors were told to stop: a clean exit.
    assert codes["shard 0"] == 0 and codes["shard 2"] == 0, f"{codes}\n{c.tail()}"
    stderr = (out / "logs" / "coordinator.log").read_text()
    assert f"shard 1 ({shard_ip(1)}:" in stderr and "connection closed" in stderr, stderr
    assert str(out) in stderr, stderr  # where the files are

    # The evidence up to the failure.
    summary = json.loads((out / "summary.json").read_text())
    assert failed["summary"] == summary
    assert summary["endReason"].startswith(f"shardFailed: shard 1 ({shard_ip(1)}:"), summary["endReason"]
    assert 5.0 <= summary["simTimeS"] < 600.0, summary
    recorded = events(out / "events.jsonl")
    assert recorded[0]["event"] == "runStarted"
    assert recorded[-1] == {"timeS": summary["simTimeS"], "event": "runEnded", "reason": summary["endReason"]}
    rows = (out / "trajectory.csv").read_text()
    assert rows.endswith("\n")
    last = rows.splitlines()[-1].split(",")
    assert float(last[0]) >= 5.0 and int(last[1]) == SHARDS * DRONES_PER_SHARD - 1, last
    assert (out / "trajectory.geojson").exists() and (out / "airspace.json").exists()
    assert_recordings_closed(out, json.loads(plan.read_text()))
    shutil.copy(plan, out / "plan.json")

    # Archive the run folder with every process's log, then verify and read it back.
    archive = f"file://{tmp_path / 'archive'}"
    put = subprocess.run(
        [sadesim, "archive", "put", str(out), archive, "--namespace", "default", "--run", "shard-killed",
         "--uid", "test", "-q"],
        capture_output=True, text=True, timeout=300,
    )
    assert put.returncode == 0, put.stdout + put.stderr
    location = f"{archive}/default/shard-killed/test"
    verify = subprocess.run([sadesim, "archive", "verify", location, "-q"], capture_output=True, text=True, timeout=300)
    assert verify.returncode == 0, verify.stdout + verify.stderr
    fetched = tmp_path / "fetched"
    get = subprocess.run([sadesim, "archive", "get", location, str(fetched), "-q"], capture_output=True, text=True, timeout=300)
    assert get.returncode == 0, get.stdout + get.stderr
    manifest = (fetched / "manifest.json").read_text()
    for name in ["logs/coordinator.log", "logs/coordinator.stdout.jsonl", *(f"logs/shard-{i}.log" for i in range(SHARDS))]:
        assert name in manifest, f"{name} not archived"
    assert "connection closed" in (fetched / "logs" / "coordinator.log").read_text()
    assert f"shard 1: {DRONES_PER_SHARD} drones" in (fetched / "logs" / "shard-1.log").read_text()
    archived = json.loads((fetched / "summary.json").read_text())
    assert archived["endReason"] == summary["endReason"]


def test_a_shard_that_stops_answering_fails_the_run_after_the_shard_timeout(sadesim, cluster, tmp_path):
    doc = scenario("shard-silent", "10m", {"mode": "scaled", "factor": 4})
    _, plan = write_plan(sadesim, doc, tmp_path)
    out = tmp_path / "out"
    c = cluster(plan, out)
    c.start_coordinator("--shard-timeout", "3")
    c.start_shards()
    progress = c.next_report(120, lambda r: r["type"] in ("failed", "finished") or (r["type"] == "progress" and r["simTimeS"] >= 2))
    assert progress["type"] == "progress", f"{progress}\n{c.tail()}"
    # A frozen shard keeps its connection open, as a host that lost power would: no FIN.
    os.kill(c.shards[2].pid, signal.SIGSTOP)
    try:
        failed = c.next_report(60, lambda r: r["type"] in ("failed", "finished"))
    finally:
        os.kill(c.shards[2].pid, signal.SIGKILL)
    assert failed["type"] == "failed" and failed["shard"] == 2, f"{failed}\n{c.tail()}"
    assert failed["reason"].startswith(f"shard 2 ({shard_ip(2)}:") and "no answer for 3 s" in failed["reason"], failed
    codes = c.wait_all(60)
    assert codes["coordinator"] != 0 and codes["shard 0"] == 0 and codes["shard 1"] == 0, codes
    summary = json.loads((out / "summary.json").read_text())
    assert summary["endReason"].startswith("shardFailed: shard 2"), summary


def write_annotations(path: pathlib.Path, annotations: dict[str, str]):
    """As the kubelet writes a downward-API file of a Pod's annotations: sorted `key="value"`
    lines, replaced atomically (a rename, as its `..data` symlink swap)."""
    tmp = path.with_suffix(".tmp")
    tmp.write_text("\n".join(f"{k}={json.dumps(v)}" for k, v in sorted(annotations.items())))
    tmp.replace(path)


def test_the_stop_annotation_ends_the_run_with_its_reason(sadesim, cluster, tmp_path):
    """The Kubernetes path of `onExit: endRun`: the operator annotates the coordinator Pod
    `sadesim.io/stop=pilotExited` and the Pod's downward-API file changes under the running
    coordinator, which ends the run after the current window with that reason."""
    doc = scenario("stopped", "10m", {"mode": "scaled", "factor": 4})
    _, plan = write_plan(sadesim, doc, tmp_path)
    control = tmp_path / "annotations"
    write_annotations(control, {"kubernetes.io/config.source": "api"})
    out = tmp_path / "out"
    c = cluster(plan, out)
    c.start_coordinator("--control-file", str(control))
    c.start_shards()
    progress = c.next_report(120, lambda r: r["type"] in ("failed", "finished") or (r["type"] == "progress" and r["simTimeS"] >= 3))
    assert progress["type"] == "progress", f"{progress}\n{c.tail()}"
    # A malformed value is refused in the log and the run goes on.
    write_annotations(control, {"kubernetes.io/config.source": "api", "sadesim.io/stop": "pilot exited"})
    more = c.next_report(60, lambda r: r["type"] in ("failed", "finished") or (r["type"] == "progress" and r["simTimeS"] >= progress["simTimeS"] + 2))
    assert more["type"] == "progress", f"{more}\n{c.tail()}"
    write_annotations(control, {"kubernetes.io/config.source": "api", "sadesim.io/stop": "pilotExited"})
    finished = c.next_report(60, lambda r: r["type"] in ("failed", "finished"))
    assert finished["type"] == "finished", f"{finished}\n{c.tail()}"
    codes = c.wait_all(60)
    assert codes == {"coordinator": 0, **{f"shard {i}": 0 for i in range(SHARDS)}}, f"{codes}\n{c.tail()}"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["endReason"] == "pilotExited", summary
    # Well before the 10 minutes of `duration`: at 4x, the poll (0.25 s) and a window.
    assert more["simTimeS"] < summary["simTimeS"] < more["simTimeS"] + 30, (more, summary)
    assert events(out / "events.jsonl")[-1] == {"timeS": summary["simTimeS"], "event": "runEnded", "reason": "pilotExited"}
    log = (out / "logs" / "coordinator.log").read_text()
    assert 'annotation sadesim.io/stop="pilot exited": expected 1 to 64 ASCII letters' in log, log
    assert_recordings_closed(out, json.loads(plan.read_text()))


def test_the_pilot_pods_wait_release_holds_the_pilot_until_the_coordinator_releases_it(sadesim, sim_worker, cluster, tmp_path):
    """The cluster path of "the pilot starts on the release": the pilot pod's init
    container `sim-worker wait-release`, on another host, polls the coordinator's airspace
    API `/healthz`. It must still wait while the shards are not there (no release), and
    exit 0 only once the coordinator has reported `pilotsReleased`."""
    doc = scenario("released", "20s", {"mode": "scaled", "factor": 2})
    _, plan = write_plan(sadesim, doc, tmp_path)
    c = cluster(plan, tmp_path / "out")
    c.start_coordinator()
    log = c._log("wait-release.log")
    wait = subprocess.Popen(
        ["ip", "netns", "exec", c.net.shards[0], sim_worker, "wait-release",
         f"http://{COORDINATOR_IP}:{AIRSPACE_PORT}/healthz"],
        stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
    )
    try:
        time.sleep(3)
        assert wait.poll() is None, f"wait-release ended before any shard was there\n{c.tail()}"
        c.start_shards()
        released = c.next_report(120, lambda r: r["type"] in ("pilotsReleased", "failed"))
        assert released["type"] == "pilotsReleased", f"{released}\n{c.tail()}"
        assert wait.wait(timeout=30) == 0, c.tail()
        assert "pilots released after" in (c.logs / "wait-release.log").read_text()
        codes = c.wait_all(120)
        assert codes == {"coordinator": 0, **{f"shard {i}": 0 for i in range(SHARDS)}}, f"{codes}\n{c.tail()}"
    finally:
        if wait.poll() is None:
            wait.kill()
            wait.wait(timeout=10)


def test_a_missing_control_file_stops_the_coordinator_before_it_listens(sim_worker, tmp_path):
    plan = tmp_path / "plan.json"
    plan.write_text("{}")
    done = subprocess.run(
        [sim_worker, "coordinator", "--plan", str(plan), "--out", str(tmp_path / "out"), "--listen", "127.0.0.1:0",
         "--control-file", str(tmp_path / "nope")],
        stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=30,
    )
    assert done.returncode == 2, done
    assert f"error: --control-file {tmp_path / 'nope'}: No such file or directory" in done.stderr, done.stderr
    assert done.stdout == "", "nothing listened"


def test_a_shard_with_a_wrong_coordinator_address_fails_within_its_connect_timeout(sadesim, sim_worker, network, tmp_path):
    _, plan = write_plan(sadesim, scenario("lost-shard", "40s", {"mode": "asFastAsPossible"}), tmp_path)
    # Nobody has 10.77.0.99 on the bridge: every attempt fails (no ARP answer).
    shard = subprocess.run(
        ["ip", "netns", "exec", network.shards[0], sim_worker, "shard", "--plan", str(plan), "--shard", "0",
         "--coordinator", "10.77.0.99:7400", "--no-mavlink", "--connect-timeout", "3"],
        capture_output=True, text=True, timeout=120,
    )
    assert shard.returncode == 2, shard.stderr
    assert "cannot reach the coordinator at 10.77.0.99:7400 within 3 s" in shard.stderr, shard.stderr
    assert "--coordinator" in shard.stderr, shard.stderr
