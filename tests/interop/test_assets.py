"""The asset bundle as a user meets it: `sadesim run` builds the world once into the user
cache, later runs load it (in --processes runs the shard processes too), a changed extract is
a new entry, a damaged bundle is found by its checksums and rebuilt; the bundle verifies with
`sadesim archive verify` and its glTF passes the Khronos validator."""
import json
import os
import pathlib
import re
import subprocess
from xml.etree import ElementTree

import osmium
from test_osm import VALIDATE_GLTF, helsinki  # noqa: F401  (the fixture)
from simrun import scripted_run

# examples/maps/helsinki.yaml's origin: its 350 m world holds Esplanadi park.
EXAMPLE_ORIGIN = (60.1700, 24.9470)
WORLD_LINE = re.compile(r"^  world: (.*)$", re.M)


def run(sadesim, doc, folder: pathlib.Path, cache: pathlib.Path, *flags) -> tuple[str, pathlib.Path]:
    path = folder / f"{doc['metadata']['name']}.yaml"
    path.write_text(json.dumps(doc))
    out = folder / "runs"
    before = set(out.glob("*/*"))
    env = dict(os.environ, SADESIM_CACHE_DIR=str(cache))
    done = subprocess.run([sadesim, "run", str(path), "--out", str(out), "-q", "--no-mavlink", *flags],
                          capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "criteria PASSED" in done.stdout, done.stdout
    line = WORLD_LINE.search(done.stdout)
    assert line, done.stdout
    (result,) = set(out.glob("*/*")) - before
    return line.group(1), result


def mission(extract) -> dict:
    return scripted_run("bundle", EXAMPLE_ORIGIN, 10, {"source": "osm", "osm": {"file": str(extract)}, "extentM": 350}, {
        "name": "hop", "count": 2,
        "homes": {"areas": [{"name": "Esplanadi park", "center": {"latitudeDeg": 60.16765, "longitudeDeg": 24.94700},
                             "radiusM": 40}]},
        "altitude": {"maxAglM": 60},
        "mission": {"speedMps": 5, "items": [{"takeoff": {"altitudeAglM": 40}}, {"land": {}}]},
    }, "40s", criteria=[{"noCrashes": {}}])


def test_a_second_run_loads_the_bundle_and_a_damaged_one_is_rebuilt(sadesim, helsinki, repo, tmp_path):  # noqa: F811
    cache = tmp_path / "cache"
    first, run1 = run(sadesim, mission(helsinki), tmp_path, cache)
    built = re.fullmatch(r"assets built: (\d+) buildings -> (file://\S+/assets/([0-9a-f]{64})/world/)", first)
    assert built, first
    entry = pathlib.Path(built.group(2).removeprefix("file://"))
    assert json.loads((run1 / "plan.json").read_text())["assetCacheKey"] == built.group(3)
    names = sorted(p.name for p in entry.iterdir())
    assert names == ["buildings.geojson", "manifest.json", "world.bin", "world.glb", "world.json"], names
    stamp = {p.name: p.stat().st_mtime_ns for p in entry.iterdir()}
    verify = subprocess.run([sadesim, "archive", "verify", str(entry)], capture_output=True, text=True)
    assert verify.returncode == 0, verify.stdout + verify.stderr

    # The same scenario again, its shards as processes: a hit, nothing rewritten, and every
    # shard process loaded the bundle rather than reading the extract.
    second, run2 = run(sadesim, mission(helsinki), tmp_path, cache, "--processes")
    assert second == f"asset cache hit: {built.group(2)}", second
    assert {p.name: p.stat().st_mtime_ns for p in entry.iterdir()} == stamp, "a hit rewrites nothing"
    log = (run2 / "shard-0.log").read_text()
    assert f"loaded from the asset bundle {built.group(2)}" in log, log
    # Same world, same flight: the trajectories of the in-process and the process run agree.
    assert (run1 / "trajectory.csv").read_bytes() == (run2 / "trajectory.csv").read_bytes()

    # One flipped byte in world.bin: found by the manifest's checksum, rebuilt, and the run
    # goes on in the rebuilt world.
    data = bytearray((entry / "world.bin").read_bytes())
    data[len(data) // 2] ^= 0x10
    (entry / "world.bin").write_bytes(bytes(data))
    third, _ = run(sadesim, mission(helsinki), tmp_path, cache)
    assert third.startswith("assets rebuilt (world.bin: sha256 mismatch"), third
    assert third.endswith(built.group(2))
    verify = subprocess.run([sadesim, "archive", "verify", str(entry)], capture_output=True, text=True)
    assert verify.returncode == 0, verify.stdout + verify.stderr


def test_a_changed_extract_is_a_new_entry(sadesim, helsinki, tmp_path):  # noqa: F811
    """The same map written again by libosmium (other blocks, same content): other bytes, so
    another key, though the buildings are the same."""
    cache = tmp_path / "cache"
    first, _ = run(sadesim, mission(helsinki), tmp_path, cache)
    rewritten = tmp_path / "rewritten.osm.pbf"
    writer = osmium.SimpleWriter(str(rewritten))
    for obj in osmium.FileProcessor(str(helsinki)):
        writer.add(obj)
    writer.close()
    assert rewritten.read_bytes() != helsinki.read_bytes()
    second, _ = run(sadesim, mission(rewritten), tmp_path, cache)
    key = lambda line: re.search(r"/assets/([0-9a-f]{64})/", line).group(1)  # noqa: E731
    assert second.startswith("assets built: ") and key(second) != key(first), (first, second)
    count = lambda line: int(re.search(r"(\d+) buildings", line).group(1))  # noqa: E731
    assert count(first) == count(second)


def test_the_bundles_gltf_passes_the_khronos_validator(sadesim, helsinki, repo, tmp_path):  # noqa: F811
    validator = repo / ".tools" / "npm" / "node_modules" / "gltf-validator"
    assert validator.exists(), "run tests/install-tools.sh"
    line, _ = run(sadesim, mission(helsinki), tmp_path, tmp_path / "cache")
    entry = pathlib.Path(re.search(r"(file://\S+)", line).group(1).removeprefix("file://"))
    script = tmp_path / "validate.js"
    script.write_text(VALIDATE_GLTF)
    checked = subprocess.run(["node", str(script), str(validator), str(entry / "world.glb")],
                             check=True, capture_output=True, text=True)
    report = json.loads(checked.stdout)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    stats = json.loads((entry / "world.json").read_text())
    assert stats["osm"]["buildings"] == stats["buildingCount"] > 50


def test_assets_build_then_show_preview_the_mapped_world(sadesim, helsinki, tmp_path):  # noqa: F811
    """`sadesim assets build` fills the cache once (a second build is a hit that rewrites
    nothing); `sadesim assets show` draws that world: a PNG of the documented size and an
    SVG with every building, the named parks libosmium finds in the extract, and the homes."""
    doc = mission(helsinki)
    path = tmp_path / "bundle.yaml"
    path.write_text(json.dumps(doc))
    cache = f"file://{tmp_path / 'cache'}"
    build = lambda: subprocess.run([sadesim, "assets", "build", str(path), "--asset-cache", cache, "-q"],  # noqa: E731
                                   capture_output=True, text=True)
    first = build()
    assert first.returncode == 0, first.stdout + first.stderr
    built = re.search(r"assets built: (\d+) buildings -> file://(\S+)", first.stdout)
    assert built, first.stdout
    entry = pathlib.Path(built.group(2))
    stamp = {p.name: p.stat().st_mtime_ns for p in entry.iterdir()}
    second = build()
    assert f"asset cache hit: file://{entry}" in second.stdout, second.stdout
    assert {p.name: p.stat().st_mtime_ns for p in entry.iterdir()} == stamp

    png, svg = tmp_path / "world.png", tmp_path / "world.svg"
    shown = subprocess.run([sadesim, "assets", "show", str(path), "--asset-cache", cache, "--png", str(png),
                            "--svg", str(svg), "-q"], capture_output=True, text=True)
    assert shown.returncode == 0, shown.stdout + shown.stderr
    assert "asset cache hit" in shown.stdout, shown.stdout
    head = png.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(head[16:20], "big") == 1400
    picture = svg.read_text()
    tree = ElementTree.fromstring(picture)
    ns = "{http://www.w3.org/2000/svg}"
    drawn = lambda cls, tag: sum(len(g.findall(f"{ns}{tag}")) for g in tree.iter(f"{ns}g") if g.get("class") == cls)  # noqa: E731
    assert drawn("buildings", "path") == int(built.group(1))
    assert drawn("open-spaces", "path") >= 1
    assert len([c for c in tree.iter(f"{ns}circle") if c.get("class") == "home"]) == doc["spec"]["fleet"][0]["count"]
    parks = {dict(a.tags).get("name") for a in osmium.FileProcessor(str(helsinki)).with_areas()
             .with_filter(osmium.filter.EntityFilter(osmium.osm.AREA))
             if dict(a.tags).get("leisure") == "park"}
    assert "Esplanadinpuisto" in parks and ">Esplanadinpuisto<" in picture
