"""The web console (`sadesim console`) in a real browser, used as a person would: Debian's
Chromium driven by npm playwright-core (tests/browser/console.mjs), MapLibre's WebGL on
SwiftShader, the local backend flying runs into a temporary folder.

- Plan: a zone drawn by clicking its corners on the map and given a ceiling in its form, a
  fleet group placed by a click and its route by two more, the origin picked; a bad count and a floor above the ceiling are reported next
  to their inputs and the messages go when fixed; the exported YAML validates with
  `sadesim validate` and holds the zone as drawn.
- Import then export of every example is byte-identical to the file.
- The quickstart launched from the page: the runs list follows it to `Succeeded`/`passed`,
  its report and 3D replay open, the archive lists it and verifies it. In real time with its
  live 3D view: the view plays in the run's page, and Stop ends the run `Aborted`.
- The cluster side (token, 401, the API server's refusal), answered by the driver.
- The plan map's frame rate while panning the 32-drone Chicago example (a measurement: see
  docs/console.md).

Every test fails if the page asks for anything off this machine, or logs an error.
Screenshots are kept in `<target>/test-artifacts/console/`; with
`SADESIM_UPDATE_SCREENSHOTS=1` a few are also copied to docs/console/ (commit them).
"""
import json
import math
import os
import pathlib
import re
import shutil
import signal
import subprocess

import pytest
import yaml

REPO = pathlib.Path(__file__).resolve().parents[2]
DRIVER = REPO / "tests" / "browser" / "console.mjs"
CHROMIUM = "/usr/bin/chromium"
ARTIFACTS = REPO / os.environ.get("CARGO_TARGET_DIR", "target") / "test-artifacts" / "console"
DOC_SHOTS = REPO / "docs" / "console"
EXAMPLES = sorted(p for p in (REPO / "examples").glob("*.yaml") if "kind: SimulationRun" in p.read_text())

pytestmark = [
    pytest.mark.skipif(not pathlib.Path(CHROMIUM).exists(), reason="needs Debian's chromium (tests/install-tools.sh)"),
    pytest.mark.skipif(not (REPO / ".tools/npm/node_modules/playwright-core").exists(), reason="needs playwright-core (tests/install-tools.sh)"),
]


@pytest.fixture(scope="module")
def console(sadesim, tmp_path_factory):
    """`sadesim console` on a free port, local runs into a temporary folder."""
    tmp = tmp_path_factory.mktemp("console")
    proc = subprocess.Popen(
        [sadesim, "console", "--listen", "127.0.0.1:0", "--runs", str(tmp / "runs"), "--scenarios", str(REPO / "examples")],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp,
        env={**os.environ, "SADESIM_CACHE_DIR": str(tmp / "cache")},
    )
    lines = []
    try:
        for line in proc.stdout:
            lines.append(line)
            m = re.search(r"(http://127\.0\.0\.1:\d+/)", line)
            if m:
                break
        else:
            raise AssertionError(f"sadesim console printed no URL: {''.join(lines)}")
        yield {"url": m.group(1), "tmp": tmp, "proc": proc}
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()


def drive(console, tmp_path, scenario, **config):
    """Runs one scenario of the browser driver; its result, after checking that the page made
    no request off this machine and logged no error."""
    cfg = tmp_path / f"{scenario}.json"
    cfg.write_text(json.dumps({"url": console["url"], "outDir": str(tmp_path), "scenario": scenario, **config}))
    done = subprocess.run(["node", str(DRIVER), str(cfg)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"the browser driver failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    report = json.loads(done.stdout.strip().splitlines()[-1])
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    for shot in report["shots"]:
        shutil.copy(shot, ARTIFACTS / pathlib.Path(shot).name)
    assert report["failure"] is None, f"the browser driver failed: {report['failure']}\nerrors: {report['errors']}"
    assert report["external"] == [], f"the page asked for URLs off this machine: {report['external']}"
    assert report["errors"] == [], f"the page reported errors: {report['errors']}"
    return report["result"]


def keep_for_docs(*names):
    """With SADESIM_UPDATE_SCREENSHOTS=1, copies screenshots into docs/console/ (PNG, each
    under 300 kB)."""
    if os.environ.get("SADESIM_UPDATE_SCREENSHOTS") != "1":
        return
    from PIL import Image

    DOC_SHOTS.mkdir(parents=True, exist_ok=True)
    for name in names:
        src = ARTIFACTS / f"{name}.png"
        dst = DOC_SHOTS / f"{name}.png"
        image = Image.open(src).convert("RGB")
        width = image.width
        while True:
            scaled = image if width == image.width else image.resize((width, round(image.height * width / image.width)), Image.LANCZOS)
            scaled.quantize(colors=128, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(dst, optimize=True)
            if dst.stat().st_size < 300_000:
                break
            width = int(width * 0.85)


def close(position, clicked, metres_per_pixel):
    """A document position within 1.5 pixels of where the mouse clicked."""
    north = (position["latitudeDeg"] - clicked["lat"]) * 111_320
    east = (position["longitudeDeg"] - clicked["lon"]) * 111_320 * math.cos(math.radians(clicked["lat"]))
    return math.hypot(north, east) <= 1.5 * metres_per_pixel


def test_a_zone_and_a_group_drawn_on_the_map_validate_live_and_export(console, sadesim, tmp_path):
    r = drive(console, tmp_path, "zone", allowHttpErrors=[422])
    # The corners clicked are the zone's polygon (within a pixel: the browser rounds the
    # mouse's position), with the ceiling typed in its form.
    assert r["drafted"] >= 4, r["drafted"]
    zone = r["zone"]
    assert len(zone["polygon"]) == 4
    for vertex, clicked in zip(zone["polygon"], r["clicked"]):
        assert close(vertex, clicked, r["metresPerPixel"]), (vertex, clicked)
    assert zone["ceiling"] == {"heightM": 90, "reference": "agl"}
    # The group's home is where the map was clicked.
    centre = r["group"]["homes"]["randomInArea"]["center"]
    assert close(centre, r["homeLatLon"], r["metresPerPixel"]), (centre, r["homeLatLon"])
    assert r["errorsBefore"] == []
    # Its route: two waypoints clicked, before the final hover and return.
    items = r["mission"]["items"]
    assert [next(iter(i)) for i in items] == ["takeoff", "waypoint", "waypoint", "loiter", "returnToLaunch"], items
    for item, clicked in zip(items[1:3], r["waypointsClicked"]):
        assert close(item["waypoint"], clicked, r["metresPerPixel"]) and item["waypoint"]["altitudeAglM"] == 30, item
    assert r["routeDrawn"] == 4, "home, two waypoints, home"
    # The origin picked on the map (its altitude kept).
    assert close(r["origin"], r["originClicked"], r["metresPerPixel"]) and r["origin"]["altitudeMslM"] == 181, r["origin"]
    # A count of 0: the validator's message right after the count's input, gone when fixed.
    assert r["countError"] and "between 1 and 10000" in r["countError"], r["countError"]
    assert r["countFixed"] is None
    # Launched meanwhile: refused (422), the page stays on the plan with the problem in place.
    assert r["launchRefused"]["flash"].startswith("not launched") and r["launchRefused"]["hash"] == "#/plan", r["launchRefused"]
    assert "between 1 and 10000" in r["launchRefused"]["countError"], r["launchRefused"]
    # A floor above the ceiling: the message after the zone's ceiling, the zone red on the map.
    assert r["ceilingError"] and "floor must be below ceiling" in r["ceilingError"], r["ceilingError"]
    assert r["zoneHighlighted"]
    assert r["ceilingFixed"] is None
    # A zone closed by a double-click on its last corner: that corner once, drawing over.
    assert len(r["triangle"]["polygon"]) == 3 and r["modeAfterTriangle"] is None, r["triangle"]
    assert r["errorsAfter"] == [] and r["status"].startswith("valid"), (r["status"], r["errorsAfter"])
    # The export: downloaded as <name>.yaml, shown in the YAML tab, valid for the CLI.
    exported = pathlib.Path(r["exported"]["path"])
    assert r["exported"]["suggested"] == "quickstart.yaml"
    text = exported.read_text()
    assert text == r["yamlTab"]
    done = subprocess.run([sadesim, "validate", str(exported)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
    doc = yaml.safe_load(text)
    drawn = [z for z in doc["spec"]["zones"] if z["name"] == zone["name"]]
    assert len(drawn) == 1
    assert drawn[0]["polygon"] == zone["polygon"]
    assert drawn[0]["ceiling"] == {"heightM": 90, "reference": "agl"}
    assert drawn[0]["floor"] == {"heightM": 10, "reference": "agl"}
    assert any(g["name"] == r["group"]["name"] and g["count"] == 3 for g in doc["spec"]["fleet"])
    assert [len(z["polygon"]) for z in doc["spec"]["zones"]] == [4, 4, 3]
    assert doc["spec"]["origin"] == r["origin"]
    keep_for_docs("plan-zone-error")


@pytest.fixture(scope="module")
def roundtrips(console, tmp_path_factory):
    """Every example imported through the file input and exported, in one browser session."""
    tmp = tmp_path_factory.mktemp("roundtrip")
    r = drive(console, tmp, "roundtrip", files=[str(p) for p in EXAMPLES])
    return {pathlib.Path(f["file"]).name: f for f in r["files"]}


@pytest.mark.parametrize("example", [p.name for p in EXAMPLES])
def test_an_imported_example_exports_byte_identical(roundtrips, example):
    f = roundtrips[example]
    source = (REPO / "examples" / example).read_bytes()
    assert f["problems"] == 0, f
    assert f["suggested"] == f"{f['name']}.yaml"
    exported = pathlib.Path(f["path"]).read_bytes()
    assert exported == source, f"{example}: the export differs from the file ({len(exported)} bytes, {len(source)} in the file)"


def test_the_quickstart_launched_from_the_page_runs_reports_replays_and_verifies(console, tmp_path):
    source = yaml.safe_load((REPO / "examples" / "quickstart.yaml").read_text())
    assert source["spec"]["clock"] == {"mode": "asFastAsPossible"}
    r = drive(console, tmp_path, "launch", file=str(REPO / "examples" / "quickstart.yaml"), timeoutMs=150000)
    assert r["runHash"].startswith("#/runs/")
    assert r["listPhase"] == "Succeeded" and r["verdict"] == "passed", r
    assert [c["state"] for c in r["criteria"]] == ["passed", "passed"], r["criteria"]
    assert r["events"] > 10
    assert r["reportHasName"] and "quickstart" in r["reportTitle"], r["reportTitle"]
    assert r["replayState"]["canvases"] >= 1 and r["replayState"]["ready"], r["replayState"]
    assert r["archiveRow"][0] == "quickstart" and "passed" in r["archiveRow"] and r["archiveRow"][-1] == "yes", r["archiveRow"]
    paths = {f["path"]: f["highlighted"] for f in r["files"]}
    assert paths.get("recording.mcap") is True and paths.get("report.html") is False, paths
    assert any(p.startswith("ulog/") and h for p, h in paths.items()), paths
    assert r["archiveEvents"] > 10
    assert r["verify"]["ok"] == "true" and r["verify"]["text"].startswith("ok"), r["verify"]
    keep_for_docs("run", "archive-entry")


def test_a_run_with_its_live_view_stopped_from_its_page_ends_aborted(console, tmp_path):
    r = drive(console, tmp_path, "stop", file=str(REPO / "examples" / "quickstart.yaml"))
    assert r["clock"] == {"mode": "realtime"} and r["rendering"] == {"enabled": True}
    # The live view embedded in the run's page drew the run as it flew.
    assert r["viewUrl"].startswith("http://127.0.0.1:"), r["viewUrl"]
    assert r["liveView"]["ready"] and r["liveView"]["frames"] > 5 and r["liveView"]["time"] > 0, r["liveView"]
    assert r["before"] == "Running" and r["after"] == "Aborted", r
    assert r["stopShown"] == 0, "the Stop button stays on an ended run"
    assert r["viewGone"] == 0, "the live view stays on an ended run"
    keep_for_docs("run-live")


def test_on_a_cluster_the_page_sends_the_users_token_and_shows_the_api_servers_refusal(console, tmp_path):
    """The cluster backend's answers are played by the browser driver (no cluster here): the
    console needs the user's token, the runs stream refuses without it, and the Kubernetes API
    server refuses the launch."""
    r = drive(console, tmp_path, "auth", file=str(REPO / "examples" / "quickstart.yaml"), allowHttpErrors=[401, 403])
    assert r["tokenBoxShown"] and "Log in with your token" in r["banner"]
    assert r["watch"][0] is None and r["watch"][-1] == "Bearer tok-123", r["watch"]
    assert r["stored"] == "tok-123" and not r["bannerAfter"]
    # The cookie carries it for links (report, replay, files): this site only.
    assert r["cookie"] == {"value": "tok-123", "sameSite": "Strict", "path": "/"}, r["cookie"]
    assert r["listed"][:3] == ["mocked-run", "team-a", "Running"] and r["listed"][3] == "25 %", r["listed"]
    assert r["namespaces"] == ["team-a", "team-b"]
    assert r["validateAuth"] == ["Bearer tok-123"]
    assert r["launch"] == {"authorization": "Bearer tok-123", "namespace": "team-b", "queue": "q1", "name": "quickstart"}
    assert 'User "alice" cannot create resource' in r["refusal"] and r["hash"] == "#/plan", r


def test_the_plan_map_pans_the_chicago_example(console, tmp_path):
    r = drive(console, tmp_path, "fps", file=str(REPO / "examples" / "chicago-museum.yaml"), seconds=5)
    print(f"\nplan map, chicago-museum ({r['drones']} drones, {r['buildings']} buildings), panning for {r['seconds']:.1f} s: "
          f"{r['fps']:.1f} frames/s (requestAnimationFrame), {r['mapRendersPerS']:.1f} map renders/s")
    assert r["drones"] == 32 and r["buildings"] > 1000
    # A measurement, not a timing test (SwiftShader on a shared 2-core machine): only a floor.
    assert r["fps"] > 2, r
    keep_for_docs("plan-chicago")
