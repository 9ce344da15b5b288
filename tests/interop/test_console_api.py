"""The console's HTTP API (`sadesim console`, local backend) against its own OpenAPI
document, docs/console-api.yaml: every answer here is checked against the document's
schema for its path, method and status (openapi-schema-validator), and what it says is
checked against the run folder and `sadesim validate` (the browser tests are
test_console.py)."""
import json
import pathlib
import re
import signal
import subprocess
import time
import urllib.error
import urllib.request

import pytest
import yaml
from openapi_schema_validator import OAS31Validator
from referencing import Registry, Resource
from referencing.jsonschema import DRAFT202012

REPO = pathlib.Path(__file__).resolve().parents[2]
SPEC = yaml.safe_load((REPO / "docs/console-api.yaml").read_text())
REGISTRY = Registry().with_resource("console-api", Resource.from_contents(SPEC, default_specification=DRAFT202012))


def conforms(path: str, method: str, status: int, body):
    """Asserts `body` matches the document's JSON schema of that answer (resolved inside
    the document, so every `$ref` in it works)."""
    operation = SPEC["paths"][path][method]
    assert str(status) in operation["responses"], f"{method.upper()} {path} answered {status}, not in the document"
    response = operation["responses"][str(status)]
    pointer = "/paths/" + path.replace("~", "~0").replace("/", "~1") + f"/{method}/responses/{status}"
    if "$ref" in response:
        pointer = response["$ref"][1:]
        response = SPEC["components"]["responses"][response["$ref"].rsplit("/", 1)[1]]
    if "schema" in response.get("content", {}).get("application/json", {}):
        schema = {"$ref": f"console-api#{pointer}/content/application~1json/schema"}
        OAS31Validator(schema, registry=REGISTRY).validate(body)


class Console:
    def __init__(self, base: str):
        self.base = base

    def call(self, method: str, path: str, body=None, text: str | None = None, spec_path: str | None = None):
        """(status, parsed body) of a call, checked against the document (`spec_path` is the
        document's path template when it differs from `path`)."""
        data = text.encode() if text is not None else (None if body is None else json.dumps(body).encode())
        request = urllib.request.Request(self.base + path, data=data, method=method)
        request.add_header("Content-Type", "text/plain" if text is not None else "application/json")
        try:
            with urllib.request.urlopen(request, timeout=120) as r:
                status, raw, kind = r.status, r.read(), r.headers.get("Content-Type", "")
        except urllib.error.HTTPError as e:
            status, raw, kind = e.code, e.read(), e.headers.get("Content-Type", "")
        parsed = json.loads(raw) if kind.startswith("application/json") else raw.decode()
        conforms(spec_path or path.split("?")[0], method.lower(), status, parsed)
        return status, parsed

    def first_event(self, path: str, until=lambda data: True, timeout_s: float = 180):
        """The first Server-Sent Event data on `path` for which `until(data)` holds."""
        deadline = time.monotonic() + timeout_s
        with urllib.request.urlopen(self.base + path, timeout=timeout_s) as stream:
            while time.monotonic() < deadline:
                line = stream.readline().decode()
                if line.startswith("data:"):
                    data = json.loads(line[5:])
                    if until(data):
                        return data
        raise AssertionError(f"no event on {path} matched within {timeout_s} s")


@pytest.fixture(scope="module")
def console(sadesim, tmp_path_factory):
    runs = tmp_path_factory.mktemp("console-runs")
    proc = subprocess.Popen([sadesim, "console", "--listen", "127.0.0.1:0", "--runs", str(runs),
                             "--scenarios", str(REPO / "examples")],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    line = proc.stdout.readline()
    m = re.search(r"http://[\d.:]+/", line)
    assert m, f"no URL in {line!r}"
    c = Console(m.group(0).rstrip("/"))
    c.runs = runs
    yield c
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=60) == 0


def quickstart_text() -> str:
    return (REPO / "examples/quickstart.yaml").read_text()


def test_info_says_local(console):
    status, info = console.call("GET", "/api/info")
    assert status == 200 and info["backend"] == "local" and info["needsToken"] is False
    assert info["archive"] == str(console.runs)


def test_a_file_parses_validates_and_exports_as_it_was(console, tmp_path, sadesim):
    status, parsed = console.call("POST", "/api/scenario/parse", text=quickstart_text())
    assert status == 200 and parsed["errors"] == []
    document = parsed["document"]
    status, text = console.call("POST", "/api/scenario/yaml", {"document": document, "original": quickstart_text()})
    assert status == 200 and text == quickstart_text()

    document["spec"]["fleet"][0]["count"] = 0
    status, checked = console.call("POST", "/api/scenario/validate", {"document": document})
    assert status == 200 and checked["plan"] is None
    assert any(e["field"] == "spec.fleet[0].count" for e in checked["errors"]), checked
    document["spec"]["fleet"][0]["count"] = 6
    status, checked = console.call("POST", "/api/scenario/validate", {"document": document})
    assert checked == {"errors": [], "plan": {"drones": 6, "durationS": 180.0}}
    # An edited document is written afresh, and the CLI agrees it is valid.
    status, text = console.call("POST", "/api/scenario/yaml", {"document": document, "original": quickstart_text()})
    out = tmp_path / "edited.yaml"
    out.write_text(text)
    assert yaml.safe_load(text)["spec"]["fleet"][0]["count"] == 6
    done = subprocess.run([sadesim, "validate", str(out)], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr

    for bad, says in [("apiVersion: v1\nkind: Pod\n", "kind"), ("spec: [", "YAML")]:
        status, body = console.call("POST", "/api/scenario/parse", text=bad)
        assert status == 400 and says in body["error"], body


def test_the_world_layers_cover_the_origin(console):
    document = console.call("POST", "/api/scenario/parse", text=quickstart_text())[1]["document"]
    status, world = console.call("POST", "/api/world", {"document": document})
    assert status == 200
    west, south, east, north = world["bounds"]
    assert west < world["origin"]["longitude"] < east and south < world["origin"]["latitude"] < north
    assert len(world["buildings"]["features"]) > 100
    # Every building lies in the world square.
    for f in world["buildings"]["features"][:200]:
        for lon, lat in f["geometry"]["coordinates"][0]:
            assert west - 1e-6 <= lon <= east + 1e-6 and south - 1e-6 <= lat <= north + 1e-6
    # Problems elsewhere do not hide the world being edited.
    document["spec"]["fleet"][0]["airframe"] = "no-such-airframe"
    status, again = console.call("POST", "/api/world", {"document": document})
    assert status == 200 and again["bounds"] == world["bounds"]
    document["spec"]["origin"]["latitude"] = 95
    status, body = console.call("POST", "/api/world", {"document": document})
    assert status == 422 and any(e["field"] == "spec.origin.latitude" for e in body["errors"]), body


def test_a_launched_run_is_watched_to_its_verdict_and_archived(console):
    document = console.call("POST", "/api/scenario/parse", text=quickstart_text())[1]["document"]
    status, body = console.call("POST", "/api/runs", {"document": document})
    assert status == 201, body
    run = body["run"]
    assert run["name"] == "quickstart" and run["drones"] == 4
    done = console.first_event("/api/runs/watch",
                               until=lambda d: any(r["id"] == run["id"] and r["phase"] in ("Succeeded", "Failed", "Aborted")
                                                   for r in d["runs"]))
    conforms("/api/runs", "get", 200, done)
    final = next(r for r in done["runs"] if r["id"] == run["id"])
    assert final["phase"] == "Succeeded" and final["verdict"] == "passed" and final["progress"] == 1.0, final
    assert final["simTimeS"] == 180.0 and final["realTimeFactor"] > 1

    status, detail = console.call("GET", f"/api/runs/{run['id']}", spec_path="/api/runs/{id}")
    assert status == 200
    assert [c["state"] for c in detail["criteria"]] == ["passed", "passed"]
    assert detail["events"] and detail["events"][0]["kind"] == "runStarted"
    folder = console.runs / "quickstart" / run["id"].split(".", 1)[1]
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["verdict"]["passed"] is True

    status, archive = console.call("GET", "/api/archive")
    entry = next(e for e in archive["runs"] if e["id"] == final["archiveId"])
    assert entry["complete"] and entry["verdict"] == "passed" and entry["drones"] == 4
    status, page = console.call("GET", f"/api/archive/{entry['id']}", spec_path="/api/archive/{id}")
    assert {"recording.mcap", "report.html", "events.jsonl"} <= {f["path"] for f in page["files"]}
    report = urllib.request.urlopen(f"{console.base}/api/archive/{entry['id']}/files/report.html").read().decode()
    assert "quickstart" in report
    status, verified = console.call("POST", f"/api/archive/{entry['id']}/verify", {}, spec_path="/api/archive/{id}/verify")
    assert verified == {"ok": True, "checked": len(page["files"]), "problems": []}
    # A changed file is found.
    with open(folder / "events.jsonl", "a") as f:
        f.write("\n")
    status, verified = console.call("POST", f"/api/archive/{entry['id']}/verify", {}, spec_path="/api/archive/{id}/verify")
    assert verified["ok"] is False and any("events.jsonl" in p for p in verified["problems"]), verified
    # The replay page and its recording.
    page = urllib.request.urlopen(f"{console.base}/replay/{entry['id']}/").read().decode()
    assert "app.js" in page
    replay = json.loads(urllib.request.urlopen(f"{console.base}/replay/{entry['id']}/replay.json").read())
    assert replay["frames"]


def test_a_stopped_run_ends_aborted_with_its_evidence(console):
    document = yaml.safe_load(quickstart_text())
    document["metadata"]["name"] = "stopped"
    document["spec"]["clock"] = {"mode": "realtime"}
    status, body = console.call("POST", "/api/runs", {"document": document})
    run = body["run"]
    console.first_event(f"/api/runs/{run['id']}/watch", until=lambda d: d["run"]["simTimeS"] > 3)
    status, body = console.call("POST", f"/api/runs/{run['id']}/stop", {}, spec_path="/api/runs/{id}/stop")
    assert status == 202
    ended = console.first_event(f"/api/runs/{run['id']}/watch", until=lambda d: d["run"]["phase"] in ("Succeeded", "Failed", "Aborted"))
    conforms("/api/runs/{id}", "get", 200, ended)
    assert ended["run"]["phase"] == "Aborted" and ended["run"]["simTimeS"] < 60, ended["run"]
    status, verified = console.call("POST", f"/api/archive/{ended['run']['archiveId']}/verify", {}, spec_path="/api/archive/{id}/verify")
    assert verified["ok"] is True


def test_bad_requests_are_refused_naming_what_is_wrong(console):
    document = yaml.safe_load(quickstart_text())
    document["spec"]["zones"] = [{"name": "z", "polygon": [[0, 0]]}]
    status, body = console.call("POST", "/api/runs", {"document": document})
    assert status == 422 and any(e["field"].startswith("spec.zones[0]") for e in body["errors"]), body
    status, body = console.call("POST", "/api/runs", {"document": yaml.safe_load(quickstart_text()), "namespace": "x"})
    assert status == 400 and "namespace" in body["error"]
    status, body = console.call("GET", "/api/runs/nope.20260101T000000Z", spec_path="/api/runs/{id}")
    assert status == 404
    # A local run serves its own live view (viewUrl); the console's view route is for clusters.
    status, body = console.call("GET", "/api/runs/nope.20260101T000000Z/view/", spec_path="/api/runs/{id}/view/{path}")
    assert status == 404 and "local runs serve their live view" in body["error"], body
    status, body = console.call("GET", "/api/archive/..", spec_path="/api/archive/{id}")
    assert status == 404
    status, body = console.call("GET", "/api/archive/a.b", spec_path="/api/archive/{id}")
    assert status == 404


def test_a_flying_run_s_page_has_its_live_view_and_camera_streams(console):
    document = yaml.safe_load(quickstart_text())
    document["metadata"]["name"] = "watched"
    document["spec"]["duration"] = "60s"
    document["spec"]["clock"] = {"mode": "realtime"}
    document["spec"]["rendering"] = {"enabled": True}
    document["spec"]["fleet"][0]["cameras"] = [{"name": "down", "widthPx": 160, "heightPx": 120,
                                                "horizontalFovDeg": 90, "rateHz": 2, "mount": {"pitchDeg": 90}}]
    status, body = console.call("POST", "/api/runs", {"document": document})
    assert status == 201, body
    run = body["run"]
    flying = console.first_event(f"/api/runs/{run['id']}/watch", until=lambda d: d["run"]["simTimeS"] > 2)
    conforms("/api/runs/{id}", "get", 200, flying)
    assert flying["viewUrl"], flying
    page = urllib.request.urlopen(flying["viewUrl"], timeout=30).read().decode()
    assert "app.js" in page
    drones = {c["drone"] for c in flying["cameras"]}
    assert drones == {f"scouts-{i}" for i in range(document["spec"]["fleet"][0]["count"])}, flying["cameras"]
    latest = flying["cameras"][0]["url"].replace("stream.mjpg", "latest.jpg")
    frame = urllib.request.urlopen(latest, timeout=30).read()
    assert frame[:3] == b"\xff\xd8\xff", "a JPEG frame"
    console.call("POST", f"/api/runs/{run['id']}/stop", {}, spec_path="/api/runs/{id}/stop")
    ended = console.first_event(f"/api/runs/{run['id']}/watch", until=lambda d: d["run"]["phase"] == "Aborted")
    assert ended["viewUrl"] is None and ended["cameras"] == []
