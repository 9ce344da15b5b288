"""The airspace API of a live run against its own contract (`docs/airspace-api.yaml`):
schemathesis generates requests for every operation from the spec (its examples, the
coverage of each parameter's edges, random data, and stateful sequences along the links
it infers) and checks every answer with all of its checks: the status and body match the
spec, no 5xx, schema-valid requests accepted and invalid ones refused, and authentication
enforced. Then every operation that declares `security` is sent without a token, with
another scheme, an empty token and tokens that are no credential of the run: each must
answer 401 as the spec says, and none may leave an event in the run's log.

The run is small (3 scripted drones over Millennium Park, no MAVLink, real-time clock)
and uses the names of the Chicago case study, so the spec's own examples (`museum-tfr`,
`public-safety-0`, `chicago-dps`) reach the authority's real decisions.
"""
import json
import os
import pathlib
import subprocess
import sys
import time
import urllib.error
import urllib.request

import pytest
import yaml

from simrun import SimRun, wait_until

REPO = pathlib.Path(__file__).resolve().parents[2]
SPEC = REPO / "docs" / "airspace-api.yaml"
DPS = "dps-token-local-only"
NEWS = "news-token-local-only"
MUSEUM = [
    {"latitudeDeg": 41.8807, "longitudeDeg": -87.6245},
    {"latitudeDeg": 41.8781, "longitudeDeg": -87.6245},
    {"latitudeDeg": 41.8781, "longitudeDeg": -87.6208},
    {"latitudeDeg": 41.8807, "longitudeDeg": -87.6208},
]
PARK = {"latitudeDeg": 41.8826, "longitudeDeg": -87.6225}
# Bounds the fuzzing phase per operation (CI runs this test): about 15 s in all.
MAX_EXAMPLES = 40


def scenario() -> dict:
    """The Chicago case study's zone, groups, operators and credentials, cut down to three
    scripted drones hovering in the park for as long as the test needs (10 min at most)."""
    hover = {"speedMps": 5, "items": [{"takeoff": {"altitudeAglM": 20}}, {"loiter": {"holdS": 600}}]}
    homes = {"randomInArea": {"name": "Millennium Park", "center": PARK, "radiusM": 100}}
    group = {"airframe": "x500", "homes": homes, "altitude": {"maxAglM": 121.92}, "mission": hover}
    return {
        "apiVersion": "sadesim.io/v1alpha1",
        "kind": "SimulationRun",
        "metadata": {"name": "airspace-fuzz"},
        "spec": {
            "origin": {"latitudeDeg": 41.8796, "longitudeDeg": -87.6237, "altitudeMslM": 181},
            "duration": "10m",
            "clock": {"mode": "realtime"},
            "seed": 7,
            "world": {"source": "procedural", "extentM": 800,
                      "openAreas": [{"name": "Millennium Park", "center": PARK, "radiusM": 150}]},
            "zones": [{
                "name": "museum-tfr",
                "polygon": MUSEUM,
                "floor": {"heightM": 0, "reference": "agl"},
                "ceiling": {"heightM": 152.4, "reference": "agl"},
                "policy": {"authorizedOperators": ["chicago-dps"], "minAltitudeAglM": 106.68,
                           "leaseDuration": "10m", "capacity": 10},
            }],
            "fleet": [
                {"name": "public-safety", "count": 2, "operator": "chicago-dps", "role": "publicSafety",
                 "credential": {"value": DPS}, **group},
                {"name": "journalists", "count": 1, "operator": "wgn-news", "role": "journalist",
                 "credential": {"value": NEWS}, **group},
            ],
        },
    }


class AirspaceRun(SimRun):
    """A `SimRun` of scripted drones without MAVLink: ready once the fleet file names the
    airspace URL and the API reports the pilots released."""

    def _wait_ready(self, timeout_s: float = 120):
        deadline = time.monotonic() + timeout_s

        def fleet_file():
            self._check_alive()
            found = sorted((self.out_root / self.name).glob("*/fleet.json"))
            return found[-1] if found else None

        path = wait_until(fleet_file, timeout_s, lambda: f"no fleet.json under {self.out_root}\n{self.log_tail()}")
        self.out_dir = path.parent
        self.fleet = json.loads(path.read_text())
        self.url = self.fleet["airspaceUrl"]

        def released():
            self._check_alive()
            try:
                return get_json(self.url + "/healthz")["pilotsReleased"]
            except OSError:
                return False

        wait_until(released, max(1.0, deadline - time.monotonic()),
                   lambda: f"{self.url}/healthz never said pilotsReleased\n{self.log_tail()}")


def get_json(url: str) -> dict:
    with urllib.request.urlopen(url, timeout=10) as r:
        return json.load(r)


def call(url: str, method: str, headers: dict, body: bytes | None = None) -> tuple[int, dict, dict]:
    request = urllib.request.Request(url, data=body, method=method, headers=headers)
    try:
        with urllib.request.urlopen(request, timeout=10) as r:
            return r.status, {k.lower(): v for k, v in r.headers.items()}, json.load(r)
    except urllib.error.HTTPError as e:
        return e.code, {k.lower(): v for k, v in e.headers.items()}, json.loads(e.read() or b"null")


@pytest.fixture(scope="module")
def live(sadesim, tmp_path_factory):
    run = AirspaceRun(sadesim, tmp_path_factory.mktemp("airspace-fuzz"), scenario(), ("--no-mavlink",))
    with run:
        yield run


# One exception to "a schema-valid request is accepted": JSON Schema cannot state that
# `altitude.minAglM` must be below `altitude.maxAglM`, so a band the schema allows may get the
# 422 `invalid_altitude_band` the spec documents for it (the Rust tests check the 422 is
# only ever that).
CONFIG = """
[[operations]]
include-operation-id = "requestEntry"
[operations.checks.positive_data_acceptance]
expected-statuses = ["2xx", "401", "403", "404", "409", "422"]
"""


def schemathesis(url: str, token: str, report: pathlib.Path, *extra: str) -> subprocess.CompletedProcess:
    """`schemathesis run` of the whole spec against `url` with every check, bounded."""
    exe = pathlib.Path(sys.executable).parent / "schemathesis"
    config = report.parent / "schemathesis.toml"
    config.write_text(CONFIG)
    return subprocess.run(
        [str(exe), "--config-file", str(config), "run", str(SPEC), "--url", url, "--checks", "all",
         "-H", f"Authorization: Bearer {token}",
         "--max-examples", str(MAX_EXAMPLES), "--seed", "20261206", "--no-color", "--report", "junit",
         "--report-junit-path", str(report), *extra],
        capture_output=True, text=True, timeout=240, env={**os.environ, "SCHEMATHESIS_TELEMETRY": "false"},
        cwd=report.parent)  # its example cache (.schemathesis/) goes there, not into the clone


def test_every_operation_answers_as_its_spec_says(live, tmp_path):
    """With the DPS credential: every check of schemathesis passes on every operation, in
    every phase (examples, coverage, fuzzing, stateful)."""
    st = schemathesis(live.url, DPS, tmp_path / "junit.xml")
    assert st.returncode == 0, st.stdout[-12000:] + st.stderr[-3000:]
    assert "8 selected / 8 total" in st.stdout, st.stdout[-3000:]
    assert "0 failures" in st.stdout or "No issues found" in st.stdout, st.stdout[-6000:]
    assert "5xx" not in st.stdout.split("SUMMARY")[-1], st.stdout[-6000:]
    # The run went on while being fuzzed.
    assert live.alive(), live.log_tail()
    assert get_json(live.url + "/healthz")["status"] == "ok"


def test_a_wrong_token_is_refused_by_every_check(live, tmp_path):
    """With a token that is no credential of the run (as the spec's security scheme is
    probed by an attacker): the same checks all pass, so no operation that needs the
    credential answered 2xx to it."""
    st = schemathesis(live.url, "not-a-credential-of-this-run", tmp_path / "junit.xml")
    assert st.returncode == 0, st.stdout[-12000:] + st.stderr[-3000:]


def secured_operations() -> list[tuple[str, str]]:
    spec = yaml.safe_load(SPEC.read_text())
    ops = [(method.upper(), path) for path, item in spec["paths"].items() for method, op in item.items()
           if isinstance(op, dict) and op.get("security")]
    assert ops, "the spec declares no secured operation"
    return ops


def test_every_secured_operation_refuses_a_missing_or_wrong_token(live):
    """Each operation with `security` answers 401 with the spec's error codes and a
    `WWW-Authenticate: Bearer` header to a missing, malformed or unknown token, for a real
    zone and lease as well as unknown ones, and nothing is logged; the same requests with
    the right credential get past authentication."""
    url = live.url
    body = json.dumps({"drone": "public-safety-0", "operator": "chicago-dps",
                       "altitude": {"minAglM": 107, "maxAglM": 121}}).encode()
    status, _, granted = call(f"{url}/zones/museum-tfr/requests", "POST",
                              {"Authorization": f"Bearer {DPS}", "Content-Type": "application/json"}, body)
    assert status == 200 and granted["verdict"] == "granted", granted
    lease = granted["lease"]["id"]
    logged = get_json(f"{url}/events?since=0&limit=10000")["next"]

    ops = secured_operations()
    assert set(ops) == {("POST", "/zones/{id}/requests"), ("DELETE", "/leases/{id}"), ("POST", "/leases/{id}/renew")}
    wrong = {
        None: "missing_token",
        "Basic ZHBzOnRva2Vu": "missing_token",
        "Bearer ": "missing_token",
        "Bearer not-a-credential": "invalid_token",
        f"Bearer {DPS[:-1]}": "invalid_token",
        f"Bearer {DPS}x": "invalid_token",
        f"Bearer {DPS.upper()}": "invalid_token",
    }
    targets = [(method, url + path.replace("{id}", ident)) for method, path in ops
               for ident in ("museum-tfr" if "zones" in path else lease, "nowhere")]
    for method, target in targets:
        for auth, code in wrong.items():
            headers = {"Content-Type": "application/json"}
            if auth is not None:
                headers["Authorization"] = auth
            status, answer_headers, answer = call(target, method, headers, body if method == "POST" else None)
            assert (status, answer["error"]) == (401, code), f"{method} {target} with {auth!r}: {status} {answer}"
            assert answer_headers.get("www-authenticate") == "Bearer", f"{method} {target}: {answer_headers}"
    assert get_json(f"{url}/events?since={logged}")["events"] == [], "a refused token left an event"
    assert get_json(f"{url}/leases/{lease}").get("releasedAtS") is None, "a refused token released the lease"

    for method, target in targets:
        headers = {"Authorization": f"Bearer {DPS}", "Content-Type": "application/json"}
        status, _, answer = call(target, method, headers, body if method == "POST" else None)
        assert status != 401, f"{method} {target} with the right credential: {status} {answer}"


# What a run writes that must not depend on who reads the API while it flies.
RESULTS = ("events.jsonl", "trajectory.csv", "trajectory.geojson", "airspace.json", "recording.mcap",
           "ulog/public-safety-0.ulg", "ulog/journalists-0.ulg")


def test_a_read_only_load_leaves_the_run_s_results_byte_for_byte_unchanged(sadesim, tmp_path):
    """The same 20-simulated-second run twice (clock scaled x2), the second while 300
    readers poll the API at 10 Hz each (3 000 requests/s offered; on 2 cores the run, the
    service and the client share the CPU): the events, the trajectory, the airspace
    records, the MCAP recording and the ULogs are byte for byte the same. Read-only
    because entry requests are evidence the run records; they would change events.jsonl."""
    sys.path.insert(0, str(REPO / "tests" / "bench"))
    import airspace_load

    doc = scenario()
    doc["spec"]["duration"] = "20s"
    doc["spec"]["clock"] = {"mode": "scaled", "factor": 2}
    path = tmp_path / "det.yaml"
    path.write_text(yaml.safe_dump(doc))

    def run(out: pathlib.Path, with_load: bool) -> tuple[pathlib.Path, dict | None]:
        proc = subprocess.Popen([sadesim, "run", str(path), "--no-mavlink", "-q", "--out", str(out)],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
        figures = None
        try:
            if with_load:
                fleet_file = wait_until(lambda: next(out.glob("*/*/fleet.json"), None) or proc.poll() is not None,
                                        120, "no fleet.json")
                assert proc.poll() is None, proc.communicate()[0]
                fleet = json.loads(fleet_file.read_text())
                wait_until(lambda: get_json(fleet["airspaceUrl"] + "/healthz")["pilotsReleased"], 60, "no release")
                figures = airspace_load.load(fleet, drones=300, rate=10, seconds=6, mix="read")
            output, _ = proc.communicate(timeout=180)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        assert proc.returncode == 0, output
        return next(out.glob("*/*/summary.json")).parent, figures

    quiet, _ = run(tmp_path / "quiet", False)
    loaded, figures = run(tmp_path / "loaded", True)
    assert figures["errors"] == 0 and figures["requests"] >= 300 * 10 * 6 * 0.95, figures
    for name in RESULTS:
        a, b = (quiet / name).read_bytes(), (loaded / name).read_bytes()
        assert a == b, f"{name} differs under load ({len(a)} vs {len(b)} bytes): {figures}"
    assert json.loads((loaded / "summary.json").read_text())["verdict"] == \
        json.loads((quiet / "summary.json").read_text())["verdict"]
