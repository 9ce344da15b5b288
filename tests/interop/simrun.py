"""A `sadesim run --no-pilot` in the background, for tests that attach their own MAVLink
clients: scenario builder, process control, the run folder's files and ground truth.

The MAVLink ports are fixed by the port plan (API link 14540+i, endpoints 24600+i, router
UDP 14550 / TCP 5760), so only one run may be alive at a time on this machine: the interop
tests run one after the other (plain `pytest`, no `-n`), and must not run alongside another
`sadesim run` or a PX4 SITL / ground station using those ports.
"""
import csv
import io
import json
import math
import os
import pathlib
import signal
import subprocess
import time

import yaml

os.environ["MAVLINK20"] = "1"  # before pymavlink is imported anywhere: MAVLink 2 framing
from pymavlink import mavutil  # noqa: E402

# Millennium Park, Chicago: open parkland in the procedural city (see examples/quickstart.yaml).
ORIGIN = {"latitudeDeg": 41.8796, "longitudeDeg": -87.6237, "altitudeMslM": 181}
PARK = {"latitudeDeg": 41.8818, "longitudeDeg": -87.6226}
HOME = {"latitudeDeg": 41.8826, "longitudeDeg": -87.6225}

# Equatorial radius; over the few hundred metres of a test the flat-earth error is < 1 cm.
EARTH_RADIUS_M = 6_378_137.0

REALTIME = {"mode": "realtime"}


def scaled(factor: float) -> dict:
    return {"mode": "scaled", "factor": factor}


def scenario(name: str, drones: int = 1, clock: dict | None = None, duration: str = "10m") -> dict:
    """A SimulationRun with one group of `drones` x500s over Millennium Park and no mission,
    so every drone is flown over MAVLink. No wind, default GNSS noise.

    `duration` bounds the run even if a test process dies without stopping it.
    """
    group = {
        "name": "solo" if drones == 1 else "swarm",
        "count": drones,
        "airframe": "x500",
        "operator": "interop-tests",
        "altitude": {"maxAglM": 60},
    }
    if drones == 1:
        group["homes"] = {"explicit": [HOME]}
    else:
        group["homes"] = {"randomInArea": {"name": "park", "center": PARK, "radiusM": 150}}
    return {
        "apiVersion": "sadesim.io/v1alpha1",
        "kind": "SimulationRun",
        "metadata": {"name": name},
        "spec": {
            "origin": ORIGIN,
            "duration": duration,
            "clock": clock or scaled(2),
            "seed": 7,
            "world": {"openAreas": [{"name": "park", "center": PARK, "radiusM": 250}]},
            "fleet": [group],
            # Required for groups without a mission; never started (--no-pilot).
            "pilot": {"command": ["sh", "-c", "echo 'run this scenario with --no-pilot' >&2; exit 1"]},
        },
    }


def scripted_run(name: str, origin: tuple, altitude_msl_m: float, world: dict, group: dict, duration: str,
                 criteria: list | None = None) -> dict:
    """A SimulationRun of one scripted `group` (it has a `mission`) at `origin` (lat, lon),
    flown as fast as possible: no pilot, no MAVLink needed."""
    spec = {
        "origin": {"latitudeDeg": origin[0], "longitudeDeg": origin[1], "altitudeMslM": altitude_msl_m},
        "duration": duration,
        "clock": {"mode": "asFastAsPossible"},
        "world": world,
        "fleet": [{"airframe": "x500", "operator": "interop-tests", **group}],
    }
    if criteria:
        spec["criteria"] = criteria
    return {"apiVersion": "sadesim.io/v1alpha1", "kind": "SimulationRun", "metadata": {"name": name}, "spec": spec}


def run_scripted(sadesim: str, doc: dict, folder: pathlib.Path) -> tuple[subprocess.CompletedProcess, pathlib.Path | None]:
    """Writes `doc` to `folder` and runs it with `sadesim run --no-mavlink -q` into
    `folder/runs`; returns the process and the run folder (None when none was made)."""
    path = folder / f"{doc['metadata']['name']}.yaml"
    path.write_text(json.dumps(doc))
    out = folder / "runs"
    run = subprocess.run([sadesim, "run", str(path), "--out", str(out), "-q", "--no-mavlink"],
                         capture_output=True, text=True)
    return run, next(out.glob(f"{doc['metadata']['name']}/*"), None)


def run_piloted(sadesim: str, scenario: pathlib.Path, out: pathlib.Path, venv_bin: pathlib.Path, timeout_s: float,
                env: dict | None = None, cwd: pathlib.Path | None = None) -> tuple[int | None, pathlib.Path | None, str]:
    """Runs `scenario` with its pilot (`sadesim run -q --out out`), the venv's `python3` first
    on PATH, in a session of its own; after `timeout_s` it is interrupted (SIGINT, then
    SIGKILL to the whole session). Returns the exit code (None when it had to be stopped),
    the run folder (None when none was made) and the end of sadesim's output and of
    pilot.log, for assertion messages."""
    env = {**os.environ, **(env or {})}
    env["PATH"] = f"{venv_bin}{os.pathsep}{env.get('PATH', '')}"  # the scenario's `python3` is the venv's
    out.mkdir(parents=True, exist_ok=True)
    log = out / "sadesim.log"
    with open(log, "wb") as sink:
        proc = subprocess.Popen([sadesim, "run", str(scenario), "--out", str(out), "-q"], cwd=cwd, stdout=sink,
                                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env, start_new_session=True)
        try:
            code = proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                pass
            code = None
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()
    name = yaml.safe_load(scenario.read_text())["metadata"]["name"]
    out_dir = next((out / name).glob("*"), None)
    pilot_log = out_dir / "pilot.log" if out_dir else None
    pilot_text = pilot_log.read_text(errors="replace") if pilot_log and pilot_log.exists() else ""
    context = f"--- sadesim ---\n{log.read_text(errors='replace')[-3000:]}\n--- pilot.log ---\n{pilot_text[-4000:]}"
    return code, out_dir, context


def pymavlink_url(url: str) -> str:
    """A fleet-file URL (MAVSDK syntax, `udpout://127.0.0.1:24600`) in pymavlink's syntax
    (`udpout:127.0.0.1:24600`)."""
    scheme, _, address = url.partition("://")
    return {"udpin": "udpin", "udpout": "udpout", "tcpout": "tcp", "tcpin": "tcpin"}[scheme] + ":" + address


def port_of(url: str) -> int:
    return int(url.rsplit(":", 1)[1])


def enu_m(home: dict, lat_deg: float, lon_deg: float, alt_msl_m: float) -> tuple[float, float, float]:
    """(east, north, up) in metres of a point relative to `home` (flat earth)."""
    north = math.radians(lat_deg - home["latitudeDeg"]) * EARTH_RADIUS_M
    east = math.radians(lon_deg - home["longitudeDeg"]) * EARTH_RADIUS_M * math.cos(math.radians(home["latitudeDeg"]))
    return east, north, alt_msl_m - home["altitudeMslM"]


def offset_deg(home: dict, east_m: float, north_m: float) -> tuple[float, float]:
    """(latitude, longitude) of the point `east_m`, `north_m` from `home` (flat earth)."""
    lat = home["latitudeDeg"] + math.degrees(north_m / EARTH_RADIUS_M)
    lon = home["longitudeDeg"] + math.degrees(east_m / (EARTH_RADIUS_M * math.cos(math.radians(home["latitudeDeg"]))))
    return lat, lon


def wait_until(predicate, timeout_s: float, what, poll_s: float = 0.1):
    """Calls `predicate` until it returns something truthy (returned) or `timeout_s` passes
    (AssertionError naming `what`; a callable `what` is called then, to describe the state)."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            detail = what() if callable(what) else what
            raise AssertionError(f"timed out after {timeout_s:.0f} s: {detail}")
        time.sleep(poll_s)


class Trajectory:
    """Reads `trajectory.csv` as the recorder appends to it (ground truth, 10 Hz)."""

    def __init__(self, path: pathlib.Path):
        self.path = path
        self._offset = 0
        self._partial = ""
        self._header: list[str] | None = None
        self.latest: dict[int, dict] = {}  # drone index -> latest row
        self.sim_time_s = 0.0  # latest time_s seen

    def poll(self) -> "Trajectory":
        if not self.path.exists():
            return self
        with open(self.path, encoding="utf-8") as f:
            f.seek(self._offset)
            chunk = f.read()
            self._offset = f.tell()
        text = self._partial + chunk
        lines = text.split("\n")
        self._partial = lines.pop()  # incomplete last line (or "")
        for line in lines:
            if not line:
                continue
            fields = next(csv.reader(io.StringIO(line)))
            if self._header is None:
                self._header = fields
                continue
            row = self._parse(dict(zip(self._header, fields)))
            self.latest[row["drone"]] = row
            self.sim_time_s = max(self.sim_time_s, row["time_s"])
        return self

    @staticmethod
    def _parse(raw: dict) -> dict:
        row = {}
        for key, value in raw.items():
            if key in ("name", "group", "mode"):
                row[key] = value
            elif key in ("armed", "on_ground", "crashed"):
                row[key] = value == "true"
            elif key == "drone":
                row[key] = int(value)
            else:
                row[key] = float(value)
        return row


class SimRun:
    """`sadesim run SCENARIO --no-pilot --out OUT [args]` as a child process.

    Use as a context manager: the run is started, awaited (run folder, trajectory rows,
    a heartbeat on drone 0's API link) and always stopped with SIGINT at the end (SIGKILL
    to its process group if it does not exit), also when the test fails.
    """

    def __init__(self, sadesim: str, tmp: pathlib.Path, doc: dict, args: tuple = ()):
        self.sadesim = sadesim
        self.doc = doc
        self.args = list(args)
        self.name = doc["metadata"]["name"]
        clock = doc["spec"]["clock"]
        self.clock_factor = {"realtime": 1.0, "scaled": clock.get("factor", 1.0)}.get(clock["mode"])
        self.tmp = tmp
        self.scenario = tmp / f"{self.name}.yaml"
        self.out_root = tmp / "out"
        self.log_path = tmp / "sadesim.log"
        self.proc: subprocess.Popen | None = None
        self.out_dir: pathlib.Path | None = None
        self.fleet: dict = {}
        self.trajectory: Trajectory | None = None
        self.returncode: int | None = None

    # -- process --------------------------------------------------------------------------

    def __enter__(self) -> "SimRun":
        self.scenario.write_text(yaml.safe_dump(self.doc, sort_keys=False))
        self.log = open(self.log_path, "wb")
        self.proc = subprocess.Popen(
            [self.sadesim, "run", str(self.scenario), "--no-pilot", "--out", str(self.out_root), "-q", *self.args],
            stdout=self.log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,  # its own process group: a stray Ctrl-C goes to pytest only
        )
        try:
            self._wait_ready()
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc):
        code = self.stop()
        if exc[0] is None:
            # Ctrl-C ends a run with 130 and keeps its output (docs/running-locally.md).
            assert code == 130, f"sadesim exited with {code} on SIGINT, expected 130\n{self.log_tail()}"
            assert (self.out_dir / "summary.json").exists(), f"no summary.json after SIGINT\n{self.log_tail()}"
        return False

    def stop(self) -> int | None:
        """SIGINT, up to 30 s to end cleanly, then SIGKILL to the process group. Idempotent."""
        if self.proc is None:
            return self.returncode
        proc, self.proc = self.proc, None
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                pass
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # anything it left in its group
        except ProcessLookupError:
            pass
        if proc.poll() is None:
            proc.wait(timeout=10)
        self.log.close()
        self.returncode = proc.returncode
        return self.returncode

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def log_tail(self, chars: int = 3000) -> str:
        text = self.log_path.read_text(errors="replace") if self.log_path.exists() else ""
        return f"--- sadesim log ({self.log_path}) ---\n{text[-chars:]}"

    def _check_alive(self):
        if not self.alive():
            raise AssertionError(f"sadesim exited early with {self.proc.returncode if self.proc else None}\n{self.log_tail()}")

    def _wait_ready(self, timeout_s: float = 90):
        deadline = time.monotonic() + timeout_s

        def left() -> float:
            return max(0.0, deadline - time.monotonic())

        def folder():
            self._check_alive()
            found = sorted((self.out_root / self.name).glob("*/fleet.json"))
            return found[-1].parent if found else None

        self.out_dir = wait_until(folder, left(), lambda: f"no run folder with fleet.json under {self.out_root}\n{self.log_tail()}")
        self.fleet = json.loads((self.out_dir / "fleet.json").read_text())
        self.trajectory = Trajectory(self.out_dir / "trajectory.csv")

        def rows():
            self._check_alive()
            return len(self.trajectory.poll().latest) == len(self.fleet["drones"])

        wait_until(rows, left(), lambda: f"no ground truth for every drone in {self.trajectory.path}\n{self.log_tail()}")

        api = pymavlink_url(self.drone(0)["mavlink"]["api"])
        link = mavutil.mavlink_connection(api, source_system=255, source_component=190)
        try:
            while True:
                self._check_alive()
                hb = link.recv_match(type="HEARTBEAT", blocking=True, timeout=1)
                if hb is not None and link.target_system == self.drone(0)["systemId"]:
                    break
                if left() <= 0:
                    raise AssertionError(f"no HEARTBEAT from drone 0 on its API link {api}\n{self.log_tail()}")
        finally:
            link.close()

    # -- fleet and ground truth -----------------------------------------------------------

    def drone(self, index: int) -> dict:
        return self.fleet["drones"][index]

    def truth(self, index: int) -> dict:
        """Latest ground-truth row of drone `index`, plus `east`, `north`, `up`: metres from
        the drone's home (flat earth; `up` from the home's ground altitude)."""
        self._check_alive()
        row = dict(self.trajectory.poll().latest[index])
        home = self.drone(index)["home"]
        row["east"], row["north"], row["up"] = enu_m(home, row["latitude_deg"], row["longitude_deg"], row["altitude_msl_m"])
        return row

    def sim_time_s(self) -> float:
        self._check_alive()
        return self.trajectory.poll().sim_time_s

    def events(self) -> list[dict]:
        path = self.out_dir / "events.jsonl"
        lines = path.read_text().splitlines() if path.exists() else []
        return [json.loads(line) for line in lines if line.strip()]


def describe_truth(row: dict) -> str:
    return (
        f"t={row['time_s']:.1f}s east={row['east']:.1f} north={row['north']:.1f} up={row['up']:.1f} m "
        f"mode={row['mode']} armed={row['armed']} on_ground={row['on_ground']} crashed={row['crashed']}"
    )
