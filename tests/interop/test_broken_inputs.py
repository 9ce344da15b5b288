"""Broken inputs as a user meets them: every file the simulator reads that a user may hand
it, broken on purpose, is refused at the command line with exit status 2 and one line that
names the file and the problem. OpenStreetMap extracts through `sadesim osm`, DEMs through
`sadesim dem`, world bundles (the asset cache's `world.bin`) through `sim-worker shard
--assets`, which loads the bundle before anything else.

One table: (case, the command's arguments made in a temporary folder, what the line must
say). The same readers are fuzzed for panics by fuzz/ (tests/fuzz.sh); their library-level
errors are unit-tested in world/src/{osm,dem}/tests.rs and world/src/bundle.rs.
"""
import hashlib
import json
import pathlib
import re
import shutil
import struct
import subprocess

import osmium
import pytest
from osmium.osm.mutable import Node, Relation, Way
from simrun import scripted_run
from test_dem import ascii_grid, gdal, surface
from test_dem import ORIGIN as DEM_ORIGIN
from test_osm import ORIGIN as OSM_ORIGIN
from test_osm import geodetic, helsinki  # noqa: F401  (the fixture)

# --- OpenStreetMap extracts -------------------------------------------------------------------


def varint(v: int) -> bytes:
    out = bytearray()
    while v >= 0x80:
        out.append((v & 0x7F) | 0x80)
        v >>= 7
    out.append(v)
    return bytes(out)


def field(number: int, payload: bytes) -> bytes:
    """A length-delimited Protocol Buffers field."""
    return varint(number << 3 | 2) + varint(len(payload)) + payload


def blob(kind: str, blob_message: bytes) -> bytes:
    """One file block: the 4-byte length, the BlobHeader (type, datasize), the Blob."""
    header = field(1, kind.encode()) + varint(3 << 3) + varint(len(blob_message))
    return struct.pack(">I", len(header)) + header + blob_message


OSM_HEADER = blob("OSMHeader", field(1, field(4, b"OsmSchema-V0.6") + field(4, b"DenseNodes")))


def extract(path: pathlib.Path, ways=(), relations=()) -> pathlib.Path:
    """An extract written by libosmium: nodes at the corners of a 2 km square around the
    origin (the file covers a 450 m world), then `ways` as `(id, tags, [(east, north), ...])`
    closed rings and `relations` as `(id, tags, [(type, ref, role), ...])`."""
    writer = osmium.SimpleWriter(str(path))
    node = 1
    for e, n in [(-1000, -1000), (1000, -1000), (1000, 1000), (-1000, 1000)]:
        lat, lon = geodetic(e, n)
        writer.add_node(Node(id=node, location=(lon, lat)))
        node += 1
    for way, tags, ring in ways:
        refs = []
        for e, n in ring:
            lat, lon = geodetic(e, n)
            writer.add_node(Node(id=node, location=(lon, lat)))
            refs.append(node)
            node += 1
        writer.add_way(Way(id=way, nodes=refs + refs[:1], tags=tags))
    for relation, tags, members in relations:
        writer.add_relation(Relation(id=relation, members=members, tags=tags))
    writer.close()
    return path


SQUARE = [(0, 0), (20, 0), (20, 20), (0, 20)]


def osm(name, make, expected, extent_m=450):
    """A case of `sadesim osm`: `make(tmp_path, helsinki)` returns the file."""
    def args(tmp_path, helsinki):
        file = make(tmp_path, helsinki)
        return file, ["osm", str(file), "--origin", f"{OSM_ORIGIN[0]},{OSM_ORIGIN[1]}", "--extent-m", str(extent_m)]
    return pytest.param("sadesim", "helsinki", args, expected, id=f"osm-{name}")


def written(name: str, data: bytes):
    def make(tmp_path, _):
        path = tmp_path / name
        path.write_bytes(data)
        return path
    return make


def read_varint(data: bytes, i: int) -> tuple[int, int]:
    value, shift = 0, 0
    while True:
        value |= (data[i] & 0x7F) << shift
        shift += 7
        i += 1
        if data[i - 1] < 0x80:
            return value, i


def flip_in_first_data_blob(data: bytes) -> bytes:
    """`data` with one byte flipped in the middle of its second block (the first OSMData,
    zlib-compressed in every real extract)."""
    pos = 0
    for _ in range(2):
        header_len = struct.unpack(">I", data[pos:pos + 4])[0]
        header, i, size = data[pos + 4:pos + 4 + header_len], 0, None
        while i < len(header):  # BlobHeader: 1 type (bytes), 2 indexdata (bytes), 3 datasize
            key, i = read_varint(header, i)
            value, i = read_varint(header, i)
            if key & 7 == 2:
                i += value
            elif key >> 3 == 3:
                size = value
        start = pos + 4 + header_len
        pos = start + size
    flipped = bytearray(data)
    flipped[start + size // 2] ^= 0x55
    return bytes(flipped)


OSM_CASES = [
    osm("missing", lambda tmp, _: tmp / "missing.osm.pbf", "failed to read"),
    osm("empty", written("empty.osm.pbf", b""), "byte 0: empty file"),
    osm("xml-not-pbf", written("city.osm.pbf", b"<?xml version='1.0'?><osm version='0.6'></osm>"),
        "byte 0: not an OSM PBF file"),
    osm("truncated", lambda tmp, h: written("cut.osm.pbf", h.read_bytes()[:100_000])(tmp, h), "truncated"),
    osm("flipped-zlib-byte", lambda tmp, h: written("flipped.osm.pbf", flip_in_first_data_blob(h.read_bytes()))(tmp, h),
        "zlib"),
    osm("data-before-header", written("data.osm.pbf", blob("OSMData", field(1, b""))),
        'the first blob is "OSMData", expected "OSMHeader"'),
    osm("zstd-block", written("zstd.osm.pbf", OSM_HEADER + blob("OSMData", varint(2 << 3) + varint(5) + field(7, b"\x28\xb5"))),
        "not supported: zstd-compressed blob"),
    osm("required-feature", written("history.osm.pbf", blob("OSMHeader", field(1, field(4, b"HistoricalInformation")))),
        'requires feature "HistoricalInformation"'),
    osm("extent-too-large", lambda tmp, h: h, "the extract covers longitude", extent_m=2000),
    osm("negative-height", lambda tmp, _: extract(tmp / "negative.osm.pbf", ways=[(42, {"building": "yes", "height": "-5"}, SQUARE)]),
        'way 42: tag height="-5": expected a height >= 0'),
    osm("negative-levels", lambda tmp, _: extract(tmp / "levels.osm.pbf", ways=[(43, {"building:part": "yes", "building:levels": "-2"}, SQUARE)]),
        'way 43: tag building:levels="-2": expected a number of storeys >= 0'),
    osm("relation-member-missing", lambda tmp, _: extract(
        tmp / "cut-relation.osm.pbf", relations=[(7, {"type": "multipolygon", "building": "yes"}, [("w", 99, "outer")])]),
        "no building within world.extentM 450 m of the origin: check spec.origin (is it inside the extract?) and the "
        "extent; 1 area of the file skipped as incomplete, the first relation 7: member way 99 is not in the file"),
    osm("no-building", lambda tmp, _: extract(tmp / "park.osm.pbf", ways=[(5, {"leisure": "park"}, SQUARE)]),
        "no building within world.extentM 450 m"),
]

# --- DEMs -------------------------------------------------------------------------------------


def dem(name, make, expected, extent_m=1000):
    def args(tmp_path, _):
        file = make(tmp_path)
        return file, ["dem", str(file), "--origin", f"{DEM_ORIGIN[0]},{DEM_ORIGIN[1]}", "--extent-m", str(extent_m)]
    return pytest.param("sadesim", None, args, expected, id=f"dem-{name}")


def geotiff(name: str, *options: str, cols: int = 80, rows: int = 40):
    """A GeoTIFF written by GDAL from the surface of test_dem.py (`options` for
    gdal_translate; a leading "warp" uses gdalwarp)."""
    def make(tmp_path):
        asc = tmp_path / f"{name}.asc"
        ascii_grid(asc, surface, cols=cols, rows=rows)
        tif = tmp_path / f"{name}.tif"
        if options[:1] == ("warp",):
            gdal("gdalwarp", "-q", *options[1:], str(asc), str(tif))
        else:
            gdal("gdal_translate", "-q", *options, str(asc), str(tif))
        return tif
    return make


def cut(make, keep: int):
    def cut_file(tmp_path):
        path = make(tmp_path)
        path.write_bytes(path.read_bytes()[:keep])
        return path
    return cut_file


SRTM_BYTES = 1201 * 1201 * 2

DEM_CASES = [
    dem("no-georeference", geotiff("plain"), "no georeferencing"),
    dem("web-mercator", geotiff("mercator", "warp", "-s_srs", "EPSG:4326", "-t_srs", "EPSG:3857"),
        "unsupported coordinate reference system EPSG:3857"),
    dem("lzw", geotiff("lzw", "-a_srs", "EPSG:4326", "-co", "COMPRESS=LZW"), "LZW compression"),
    dem("bigtiff", geotiff("big", "-a_srs", "EPSG:4326", "-co", "BIGTIFF=YES"), "BigTIFF"),
    dem("three-bands", geotiff("rgb", "-a_srs", "EPSG:4326", "-b", "1", "-b", "1", "-b", "1"),
        "3 samples per pixel (a DEM has one band)"),
    dem("truncated", cut(geotiff("good", "-a_srs", "EPSG:4326"), 4000), "truncated"),
    dem("one-pixel", geotiff("pixel", "-a_srs", "EPSG:4326", cols=1, rows=1), "1 x 1 pixels: at least 2 x 2"),
    dem("too-small-for-the-extent", geotiff("small", "-a_srs", "EPSG:4326"),
        "does not cover world.extentM 3000 m around the origin", extent_m=3000),
    dem("png-named-tif", lambda tmp: written("dem.tif", b"\x89PNG\r\n\x1a\n" + bytes(64))(tmp, None),
        "neither a GeoTIFF (no TIFF header) nor an SRTM tile"),
    dem("hgt-wrong-size", lambda tmp: written("N60E024.hgt", bytes(1000))(tmp, None),
        "N60E024.hgt: not a readable DEM: 1000 bytes; an SRTM tile has 2884802"),
    dem("hgt-unnamed", lambda tmp: written("tile.hgt", bytes(SRTM_BYTES))(tmp, None),
        "an SRTM tile is named by its south-west corner"),
]

# --- world bundles ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bundle(sadesim, sim_worker, tmp_path_factory):
    """A plan and its world bundle (`sadesim plan`, `sim-worker assets`): `(plan.json, entry
    folder)` of a small procedural world."""
    folder = tmp_path_factory.mktemp("bundle")
    origin = (41.8781, -87.6298)
    doc = scripted_run("broken-bundle", origin, 181, {"extentM": 300}, {
        "name": "one", "count": 1,
        "homes": {"explicit": [{"latitudeDeg": origin[0], "longitudeDeg": origin[1]}]},
        "altitude": {"maxAglM": 60},
        "mission": {"speedMps": 5, "items": [{"takeoff": {"altitudeAglM": 10}}, {"land": {}}]},
    }, "20s")
    scenario = folder / "scenario.yaml"
    scenario.write_text(json.dumps(doc))
    plan = folder / "plan.json"
    made = subprocess.run([sadesim, "plan", str(scenario), "--json"], check=True, capture_output=True, text=True)
    plan.write_text(made.stdout)
    built = subprocess.run([sim_worker, "assets", "--plan", str(plan), "--archive", f"file://{folder / 'archive'}"],
                           check=True, capture_output=True, text=True)
    url = re.search(r"file://(\S+/world/)", built.stdout)
    assert url, built.stdout
    return plan, pathlib.Path(url.group(1))


def world_bin(name, change, expected, manifest="updated"):
    """A case of `sim-worker shard --assets`: the bundle with world.bin replaced by
    `change(bytes)`, its manifest updated to match (a bundle that verifies but does not
    decode: written by another build), left as it was (damaged), or removed (partial)."""
    def args(tmp_path, bundle):
        plan, entry = bundle
        case = tmp_path / "world"
        shutil.copytree(entry, case)
        data = change((case / "world.bin").read_bytes())
        (case / "world.bin").write_bytes(data)
        if manifest == "updated":
            doc = json.loads((case / "manifest.json").read_text())
            for f in doc["files"]:
                if f["path"] == "world.bin":
                    f["size"], f["sha256"] = len(data), hashlib.sha256(data).hexdigest()
            doc["totalBytes"] = sum(f["size"] for f in doc["files"])
            (case / "manifest.json").write_text(json.dumps(doc))
        elif manifest == "removed":
            (case / "manifest.json").unlink()
            return case / "manifest.json", ["shard", "--plan", str(plan), "--shard", "0", "--coordinator", "127.0.0.1:9",
                                    "--no-mavlink", "--connect-timeout", "1", "--assets", f"file://{case}/"]
        return case / "world.bin", ["shard", "--plan", str(plan), "--shard", "0", "--coordinator", "127.0.0.1:9",
                                    "--no-mavlink", "--connect-timeout", "1", "--assets", f"file://{case}/"]
    return pytest.param("sim_worker", "bundle", args, expected, id=f"bundle-{name}")


BUNDLE_CASES = [
    world_bin("zip-not-world", lambda b: b"PK\x03\x04" + b[4:], 'world.bin: not a SADE-SIM world: expected the magic bytes "SADEWRLD"'),
    world_bin("older-format", lambda b: b[:8] + struct.pack("<I", 1) + b[12:],
              "world.bin: world format version 1 at byte 8; this build reads version 2"),
    world_bin("truncated", lambda b: b[:len(b) // 2], "world.bin: world data from byte 12"),
    world_bin("trailing-bytes", lambda b: b + b"\0\0\0", "world.bin: world data: 3 bytes after the end of the world"),
    world_bin("flipped-byte", lambda b: b[:100] + bytes([b[100] ^ 0x10]) + b[101:], "world.bin: does not match the manifest",
              manifest="stale"),
    world_bin("no-manifest", lambda b: b, "incomplete run: no manifest.json", manifest="removed"),
]


@pytest.mark.parametrize("binary, given, make, expected", OSM_CASES + DEM_CASES + BUNDLE_CASES)
def test_a_broken_input_is_one_line_naming_the_file_and_the_problem(binary, given, make, expected, request, tmp_path):
    """`binary` (a fixture: sadesim or sim_worker) on the file `make(tmp_path, fixture
    given)` returns, with the arguments it returns."""
    file, args = make(tmp_path, request.getfixturevalue(given) if given else None)
    run = subprocess.run([request.getfixturevalue(binary), *args], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2, run
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1, run.stderr
    assert str(file) in lines[0] or file.name in lines[0], f"the file is not named: {lines[0]}"
    assert expected in lines[0], lines[0]
