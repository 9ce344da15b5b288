"""The live 3D view and the replay, in a real browser (Debian's Chromium driven by npm
playwright-core, WebGL on SwiftShader): the tests read the screenshots' pixels.

- Live: the quickstart with `rendering.enabled` shows the museum zone as a pink volume
  where the zone projects, and a drone marker that moves between two screenshots.
- Replay: `sadesim view` on that run's folder scrubs to a time and draws the drones where
  `trajectory.csv` says they were then (and not where they were 5 s later).

Screenshots are kept as test artifacts in `<target>/test-artifacts/view/`.
"""
import csv
import json
import math
import os
import pathlib
import re
import signal
import subprocess
import time

import pytest
import yaml
from PIL import Image

from test_archive import s3  # noqa: F401  (the fixture: a moto S3 server)

REPO = pathlib.Path(__file__).resolve().parents[2]
DRIVER = REPO / "tests" / "browser" / "drive.mjs"
CHROMIUM = "/usr/bin/chromium"
# The scouts' group colour (the first of sim-worker's GROUP_COLOURS) and the zones' pink.
SCOUTS = (0x4E, 0x79, 0xA7)
# A camera over Grant Park looking north-west: the museum zone in the foreground, the
# scouts over Millennium Park behind it (ENU metres from the run origin).
EYE = [200.0, -240.0, 520.0]
TARGET = [40.0, 160.0, 20.0]
HIDE_LABELS = "document.getElementById('labels').style.visibility = 'hidden'"

pytestmark = pytest.mark.skipif(not pathlib.Path(CHROMIUM).exists(), reason="needs Debian's chromium (tests/install-tools.sh)")


def read_line_matching(proc, pattern, timeout_s):
    """The first match of `pattern` in the process's output lines, within `timeout_s` (a
    thread reads the pipe, so lines that arrive together are all seen)."""
    import queue
    import threading

    if not hasattr(proc, "lines"):
        proc.lines = queue.Queue()

        def pump():
            for line in proc.stdout:
                proc.lines.put(line)
            proc.lines.put(None)

        threading.Thread(target=pump, daemon=True).start()
    deadline = time.monotonic() + timeout_s
    seen = []
    while (left := deadline - time.monotonic()) > 0:
        try:
            line = proc.lines.get(timeout=left)
        except queue.Empty:
            break
        if line is None:
            break
        seen.append(line)
        m = re.search(pattern, line)
        if m:
            return m
    raise AssertionError(f"no line matching {pattern!r} within {timeout_s} s; got: {''.join(seen)[-2000:]}")


def drive(tmp_path, url, steps):
    config = tmp_path / f"steps-{len(list(tmp_path.glob('steps-*')))}.json"
    config.write_text(json.dumps({"url": url, "outDir": str(tmp_path), "steps": steps}))
    done = subprocess.run(["node", str(DRIVER), str(config)], capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, f"the browser driver failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    report = json.loads(done.stdout.strip().splitlines()[-1])
    errors = [line for line in report["console"] if line.startswith(("pageerror", "error"))]
    assert not errors, f"the page reported errors: {errors}"
    return report["results"]


def keep(*paths):
    """Copies screenshots to `<target>/test-artifacts/view/` (CI keeps them to look at)."""
    import shutil

    folder = REPO / os.environ.get("CARGO_TARGET_DIR", "target") / "test-artifacts" / "view"
    folder.mkdir(parents=True, exist_ok=True)
    for p in paths:
        shutil.copy(p, folder / pathlib.Path(p).name)


def colour_count(image, pixel, colour, half=6, tolerance=40):
    """Pixels within `half` px of `pixel` whose every channel is within `tolerance` of `colour`."""
    x0, y0 = round(pixel[0]), round(pixel[1])
    n = 0
    for y in range(y0 - half, y0 + half + 1):
        for x in range(x0 - half, x0 + half + 1):
            if 0 <= x < image.width and 0 <= y < image.height:
                p = image.getpixel((x, y))
                if all(abs(p[k] - colour[k]) <= tolerance for k in range(3)):
                    n += 1
    return n


def pink_fraction(image, pixel, half=5):
    """The share of pixels near `pixel` tinted by the zones' translucent pink (red and blue
    well above green; the city's greys and greens are not)."""
    x0, y0 = round(pixel[0]), round(pixel[1])
    pixels = [image.getpixel((x, y)) for y in range(y0 - half, y0 + half + 1) for x in range(x0 - half, x0 + half + 1)]
    return sum(1 for r, g, b, *_ in pixels if r - g > 30 and b - g > 5) / len(pixels)


def zone_points(scene):
    """Points inside the museum zone half-way up (its centroid, and half-way from it to each
    corner: a building of the procedural city may hide some of them from the test's camera),
    and a point as high 150 m east of the zone."""
    zone = next(z for z in scene["zones"] if z["name"] == "museum")
    c = zone["corners"]
    e = sum(p[0] for p in c) / len(c)
    n = sum(p[1] for p in c) / len(c)
    u = sum((p[2] + p[3]) / 2 for p in c) / len(c)
    east_edge = max(p[0] for p in c)
    inside = [[e, n, u]] + [[(e + p[0]) / 2, (n + p[1]) / 2, u] for p in c]
    return inside, [east_edge + 150.0, n, u]


@pytest.fixture(scope="module")
def live(sadesim, tmp_path_factory):
    """The quickstart with the live view, at 2x real time for 40 simulated seconds."""
    tmp = tmp_path_factory.mktemp("view")
    doc = yaml.safe_load((REPO / "examples" / "quickstart.yaml").read_text())
    doc["spec"]["duration"] = "40s"
    doc["spec"]["clock"] = {"mode": "scaled", "factor": 2}
    doc["spec"]["rendering"] = {"enabled": True}
    scenario = tmp / "quickstart-view.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    proc = subprocess.Popen(
        [sadesim, "run", str(scenario), "--out", str(tmp / "runs"), "--no-mavlink"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp,
        env={**os.environ, "SADESIM_CACHE_DIR": str(tmp / "cache")},
    )
    try:
        url = read_line_matching(proc, r"live view: (http://\S+)", 300).group(1)
        yield {"url": url, "proc": proc, "tmp": tmp}
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=120)


def test_the_live_view_shows_the_zone_and_moving_drones(live, tmp_path):
    import urllib.request

    scene = json.load(urllib.request.urlopen(live["url"] + "scene.json"))
    assert scene["mode"] == "live" and scene["worldModel"]
    inside_zone, beside_zone = zone_points(scene)
    results = drive(tmp_path, live["url"], [
        {"waitFor": "window.sadesimView && window.sadesimView.ready && window.sadesimView.frames > 0", "timeoutMs": 90000},
        # Airborne and cruising: released at 2.8 s (once the heights have settled), the
        # drones end their climb at about 22 s and fly to their first waypoint.
        {"waitFor": "window.sadesimView.time > 24", "timeoutMs": 90000},
        {"eval": f"window.sadesimView.lookAt({EYE}, {TARGET})"},
        {"eval": "[...document.querySelectorAll('.label')].filter(l => l.style.display !== 'none').map(l => l.textContent)"},
        # Name labels are HTML over the canvas: one drone's name can cover another's marker.
        {"eval": HIDE_LABELS},
        {"shot": "live-1", "project": [*inside_zone, beside_zone]},
        {"sleepMs": 2500},
        {"shot": "live-2", "project": [*inside_zone, beside_zone]},
        # The run ends: the server ends the stream after `runEnded` and the page stops
        # listening (a cut connection would be a console error, which `drive` refuses).
        {"waitFor": "document.getElementById('status').textContent === 'run ended: duration'", "timeoutMs": 90000},
    ])
    first, second = results[5], results[7]
    keep(first["path"], second["path"])
    shown_labels = results[3]["value"]
    assert "museum" in shown_labels and {d["name"] for d in scene["drones"]} <= set(shown_labels), shown_labels
    assert second["time"] > first["time"], "the stream moved on between the screenshots"
    for shot in (first, second):
        image = Image.open(shot["path"]).convert("RGB")
        *inside, beside = shot["points"]
        pink = [pink_fraction(image, p["pixel"]) for p in inside]
        assert max(pink) > 0.8, f"no zone pink at any of the zone's pixels {[p['pixel'] for p in inside]}: {pink}"
        assert pink_fraction(image, beside["pixel"]) < 0.2, f"pink 150 m east of the zone at {beside['pixel']}"
    image1 = Image.open(first["path"]).convert("RGB")
    image2 = Image.open(second["path"]).convert("RGB")
    moved = []
    for d1, d2 in zip(first["drones"], second["drones"]):
        p1, p2 = d1["pixel"], d2["pixel"]
        assert colour_count(image1, p1, SCOUTS) >= 50, f"no drone marker at {p1} in {first['path']}"
        assert colour_count(image2, p2, SCOUTS) >= 50, f"no drone marker at {p2} in {second['path']}"
        others = [d["pixel"] for d in second["drones"]]
        alone = all(math.dist(p1[:2], o[:2]) > 15 for o in others)
        if math.dist(p1[:2], p2[:2]) > 15 and alone:
            # Only a trail line (a pixel wide) is left where the marker was.
            assert colour_count(image2, p1, SCOUTS) < 30, f"the marker stayed at {p1}"
            moved.append(d1["enu"])
    assert moved, "no drone marker moved on the screen between the screenshots"


def test_a_replay_scrubs_to_where_the_trajectory_says(live, sadesim, tmp_path):
    proc = live["proc"]
    proc.communicate(timeout=240)  # the 40 s run ends by itself
    run_dir = next((live["tmp"] / "runs" / "quickstart").iterdir())
    assert (run_dir / "manifest.json").exists()
    rows = list(csv.DictReader((run_dir / "trajectory.csv").open()))

    def at(t):
        picked = [r for r in rows if abs(float(r["time_s"]) - t) < 1e-6]
        assert len(picked) == 4, f"trajectory.csv has no row for every drone at {t} s"
        return [[float(r["east_m"]), float(r["north_m"]), float(r["up_m"])] for r in sorted(picked, key=lambda r: int(r["drone"]))]

    t, later = 22.0, 32.0
    viewer = subprocess.Popen(
        [sadesim, "view", f"file://{run_dir}", "--listen", "127.0.0.1:0"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        env={**os.environ, "SADESIM_CACHE_DIR": str(live["tmp"] / "cache")},
    )
    try:
        url = read_line_matching(viewer, r"(http://127\.0\.0\.1:\d+/)", 120).group(1)
        results = drive(tmp_path, url, [
            {"waitFor": "window.sadesimView && window.sadesimView.ready", "timeoutMs": 90000},
            {"eval": f"window.sadesimView.lookAt({EYE}, {TARGET})"},
            {"eval": HIDE_LABELS},
            {"eval": f"window.sadesimView.seek({t})"},
            {"shot": "replay", "project": at(t) + at(later)},
        ])
    finally:
        viewer.send_signal(signal.SIGINT)
        output, _ = viewer.communicate(timeout=30)
    # 0: the viewer's own handler stopped it (killed by the signal it would be -2).
    assert viewer.returncode == 0, output
    shot = results[-1]
    keep(shot["path"])
    assert abs(shot["time"] - t) < 1e-9
    image = Image.open(shot["path"]).convert("RGB")
    now, then = shot["points"][:4], shot["points"][4:]
    for p in now:
        assert colour_count(image, p["pixel"], SCOUTS) >= 50, f"no drone where trajectory.csv puts it at {t} s: {p}"
    apart = [q for p, q in zip(now, then) if all(math.dist(q["pixel"][:2], o["pixel"][:2]) > 15 for o in now)]
    assert apart, "the drones did not move between the two times"
    for q in apart:
        assert colour_count(image, q["pixel"], SCOUTS) < 30, f"a drone drawn where it was only at {later} s: {q}"


def free_port():
    """A free port below Linux's ephemeral range (32768+): a client that retries a port in
    that range can connect to itself (TCP simultaneous open) and hold it."""
    import random
    import socket

    for port in random.sample(range(20000, 32000), 200):
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise AssertionError("no free port in 20000-32000")


def test_the_renderer_role_serves_the_coordinators_stream(sadesim, sim_worker, tmp_path):
    """The cluster path as separate processes: `sim-worker renderer` (started first, as a
    pod may be) follows `sim-worker coordinator --view-bind` and serves its frames and
    events to a browser's EventSource request."""
    import urllib.request

    doc = yaml.safe_load((REPO / "examples" / "quickstart.yaml").read_text())
    doc["spec"]["duration"] = "30s"
    doc["spec"]["clock"] = {"mode": "scaled", "factor": 2}
    doc["spec"]["rendering"] = {"enabled": True}
    scenario = tmp_path / "quickstart.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    planned = subprocess.run([sadesim, "plan", str(scenario), "--json"], capture_output=True, text=True, timeout=120)
    assert planned.returncode == 0, planned.stderr
    plan = tmp_path / "plan.json"
    plan.write_text(planned.stdout)
    drones = len(json.loads(planned.stdout)["drones"])
    feed, page = free_port(), free_port()
    procs = []

    def start(*args, **kw):
        p = subprocess.Popen([sim_worker, *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)
        procs.append(p)
        return p

    try:
        renderer = start("renderer", "--plan", str(plan), "--listen", f"127.0.0.1:{page}", "--feed", f"127.0.0.1:{feed}")
        url = read_line_matching(renderer, r"renderer: serving (http://\S+)", 120).group(1)
        coordinator = start("coordinator", "--plan", str(plan), "--listen", "127.0.0.1:0", "--out", str(tmp_path / "out"),
                            "--airspace-bind", "127.0.0.1:0", "--view-bind", f"127.0.0.1:{feed}")
        shard_link = read_line_matching(coordinator, r'"address":"([0-9.:]+)"', 120).group(1)
        start("shard", "--plan", str(plan), "--shard", "0", "--coordinator", shard_link, "--no-mavlink")
        scene = json.load(urllib.request.urlopen(url + "scene.json"))
        assert scene["mode"] == "live" and len(scene["drones"]) == drones
        events, frame = [], None
        with urllib.request.urlopen(url + "live", timeout=60) as stream:
            kind = None
            for raw in stream:
                line = raw.decode().rstrip("\n")
                if line.startswith("event:"):
                    kind = line.split(":", 1)[1].strip()
                elif line.startswith("data:"):
                    data = json.loads(line.split(":", 1)[1])
                    if kind == "event":
                        events.append(data["event"])
                    elif kind == "frame" and data["t"] > 3:
                        frame = data
                        break
        assert "runStarted" in events and "takeoff" in events, events
        assert len(frame["p"]) == 3 * drones and len(frame["s"]) == drones
        assert frame["air"] == drones, frame
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.communicate(timeout=30)


def replay_json(sadesim, location, env):
    """`sadesim view LOCATION` on a free port: its /replay.json, then the viewer is stopped
    with Ctrl-C. It starts with SIGINT ignored, as `sadesim view ... &` in a script starts
    it: the viewer must still stop (it handles SIGINT itself)."""
    import urllib.request

    viewer = subprocess.Popen([sadesim, "view", location, "--listen", "127.0.0.1:0"], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, env={**os.environ, **env},
                              preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        url = read_line_matching(viewer, r"(http://127\.0\.0\.1:\d+/)", 120).group(1)
        replay = json.load(urllib.request.urlopen(url + "replay.json"))
    finally:
        viewer.send_signal(signal.SIGINT)
        output, _ = viewer.communicate(timeout=30)
    # 0: the viewer's own handler stopped it (killed by the signal it would be -2).
    assert viewer.returncode == 0, output
    return replay


def test_an_archived_run_replays_as_its_folder_does(live, sadesim, s3, tmp_path):
    """`sadesim view s3://...` reads the run from object storage (each file checked against
    the manifest) and gives the same frames as the local folder; a tampered recording is
    refused, naming the file."""
    from test_archive import ARCHIVE, AWS_ENV, BUCKET, PREFIX, sadesim_cmd

    live["proc"].communicate(timeout=240)
    run_dir = next((live["tmp"] / "runs" / "quickstart").iterdir())
    put = sadesim_cmd(sadesim, "archive", "put", str(run_dir), ARCHIVE, "--run", "quickstart", "--uid", "view-1")
    assert put.returncode == 0, put.stdout + put.stderr
    url = f"{ARCHIVE}/default/quickstart/view-1"
    local = replay_json(sadesim, str(run_dir), {})
    archived = replay_json(sadesim, url, AWS_ENV)
    assert archived["frames"] == local["frames"] and archived["events"] == local["events"]
    assert len(local["frames"]) == round(local["endS"] * local["rateHz"]) + 1

    key = f"{PREFIX}/default/quickstart/view-1/recording.mcap"
    body = s3.get_object(Bucket=BUCKET, Key=key)["Body"].read()
    s3.put_object(Bucket=BUCKET, Key=key, Body=body[:-100] + bytes(100))
    refused = subprocess.run([sadesim, "view", url, "--listen", "127.0.0.1:0"], capture_output=True, text=True,
                             env={**os.environ, **AWS_ENV}, timeout=120)
    assert refused.returncode != 0
    assert "recording.mcap" in refused.stderr, refused.stderr
