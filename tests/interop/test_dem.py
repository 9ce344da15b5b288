"""The DEM reader (`sadesim dem`, `sadesim_world::dem`) on GeoTIFFs written by GDAL
(Debian's `gdal-bin`, installed by tests/install-tools.sh), checked against GDAL's own readers: `gdallocationinfo` for the
values, `gdaltransform` (PROJ) for the UTM projection.
"""
import csv
import json
import math
import subprocess

import pytest
from simrun import run_scripted, scripted_run
from test_osm import helsinki  # noqa: F401  (the fixture)

ORIGIN = (60.17, 24.94)
# The ASCII grid's lower-left corner and cell size, degrees: 0.08 deg x 0.04 deg.
WEST, SOUTH, CELL, COLS, ROWS = 24.90, 60.15, 0.001, 80, 40


def surface(lon, lat):
    """A hill and a slope, metres: not bilinear, so only pixel centres compare exactly."""
    return 15.0 + 400.0 * (lat - SOUTH) + 40.0 * math.exp(-(((lon - 24.94) / 0.01) ** 2 + ((lat - 60.17) / 0.005) ** 2))


def ascii_grid(path, f, west=WEST, south=SOUTH, cell=CELL, cols=COLS, rows=ROWS):
    lines = [f"ncols {cols}", f"nrows {rows}", f"xllcorner {west}", f"yllcorner {south}", f"cellsize {cell}",
             "NODATA_value -9999"]
    for j in range(rows):
        lat = south + (rows - j - 0.5) * cell
        lines.append(" ".join(f"{f(west + (i + 0.5) * cell, lat):.4f}" for i in range(cols)))
    path.write_text("\n".join(lines) + "\n")


def gdal(*args):
    subprocess.run(list(args), check=True, capture_output=True)


def ours(sadesim, dem, points, extent_m=1000):
    args = [sadesim, "dem", str(dem), "--origin", f"{ORIGIN[0]},{ORIGIN[1]}", "--extent-m", str(extent_m), "--json"]
    for lat, lon in points:
        args += ["--at", f"{lat},{lon}"]
    run = subprocess.run(args, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout)


@pytest.mark.parametrize("options", [
    ["-ot", "Float32"],
    ["-ot", "Float32", "-co", "COMPRESS=DEFLATE", "-co", "TILED=YES", "-co", "BLOCKXSIZE=16", "-co", "BLOCKYSIZE=16"],
    ["-ot", "Int16", "-co", "COMPRESS=DEFLATE", "-co", "PREDICTOR=2"],
])
def test_geographic_geotiff_values_match_gdal_at_pixel_centres(sadesim, tmp_path, options):
    asc = tmp_path / "dem.asc"
    ascii_grid(asc, surface)
    tif = tmp_path / "dem.tif"
    gdal("gdal_translate", "-q", "-a_srs", "EPSG:4326", *options, str(asc), str(tif))
    centres = [(SOUTH + (j + 0.5) * CELL, WEST + (i + 0.5) * CELL) for i in range(5, COLS - 5, 7) for j in range(3, ROWS - 3, 5)]
    report = ours(sadesim, tif, centres)
    assert report["crs"].startswith("EPSG:4326")
    assert report["pixels"] == [COLS, ROWS]
    for point in report["at"]:
        lat, lon = point["latitudeDeg"], point["longitudeDeg"]
        theirs = float(subprocess.run(["gdallocationinfo", "-valonly", "-wgs84", str(tif), str(lon), str(lat)],
                                      check=True, capture_output=True, text=True).stdout)
        assert point["elevationM"] == pytest.approx(theirs, abs=1e-3), (lat, lon)
    # The hill's top is at the origin.
    assert report["originM"] == pytest.approx(surface(ORIGIN[1], ORIGIN[0]), abs=1.5)


def test_a_utm_geotiff_is_projected_as_proj_does(sadesim, tmp_path):
    # WGS84 / UTM 35N, 20 m pixels, a plane in easting/northing: bilinear is exact, so the
    # elevation at a WGS84 point tells where we projected it.
    e_ll, n_ll, cell = 383_000.0, 6_669_500.0, 20.0
    slope_e, slope_n = 0.03, -0.05

    def plane(e, n):
        return 50.0 + slope_e * (e - e_ll) + slope_n * (n - n_ll)

    asc = tmp_path / "utm.asc"
    ascii_grid(asc, plane, west=e_ll, south=n_ll, cell=cell, cols=250, rows=250)
    tif = tmp_path / "utm.tif"
    gdal("gdal_translate", "-q", "-a_srs", "EPSG:32635", "-ot", "Float64", str(asc), str(tif))
    points = [(60.165 + 0.003 * k, 24.925 + 0.006 * k) for k in range(6)]
    report = ours(sadesim, tif, points, extent_m=1000)
    assert report["crs"].startswith("EPSG:32635")
    projected = subprocess.run(["gdaltransform", "-s_srs", "EPSG:4326", "-t_srs", "EPSG:32635"],
                               input="".join(f"{lon} {lat}\n" for lat, lon in points),
                               check=True, capture_output=True, text=True).stdout.split("\n")
    for point, line in zip(report["at"], projected):
        e, n, _ = map(float, line.split())
        assert point["elevationM"] == pytest.approx(plane(e, n), abs=1e-3), line


def test_a_run_over_a_dem_slope_takes_off_and_flies_above_the_ground_there(sadesim, tmp_path):
    """world.terrain.dem: homes stand on the DEM's ground, AGL altitudes are above it, and the
    altitude limits are judged over it (a 5 % slope rising east)."""
    slope_per_deg = 0.05 * 55_600.0  # 5 % east, metres per degree of longitude at 60.17 N

    def ground(lon, lat):
        return 15.0 + slope_per_deg * (lon - ORIGIN[1])

    asc = tmp_path / "slope.asc"
    ascii_grid(asc, ground, west=24.92, south=60.16, cell=0.0005, cols=80, rows=40)
    tif = tmp_path / "slope.tif"
    gdal("gdal_translate", "-q", "-a_srs", "EPSG:4326", "-ot", "Float32", str(asc), str(tif))
    east_home, west_home = (ORIGIN[0], ORIGIN[1] + 0.0054), (ORIGIN[0], ORIGIN[1] - 0.0054)  # ~300 m
    doc = scripted_run("slope", ORIGIN, 15, {"extentM": 500, "terrain": {"dem": {"file": "slope.tif"}}}, {
        "name": "hover", "count": 2,
        "homes": {"explicit": [{"latitudeDeg": lat, "longitudeDeg": lon} for lat, lon in (east_home, west_home)]},
        "altitude": {"maxAglM": 25},
        "mission": {"speedMps": 5, "items": [{"takeoff": {"altitudeAglM": 20}}, {"loiter": {"holdS": 15}}]},
    }, "40s", criteria=[{"altitudeLimitsRespected": {}}, {"noCrashes": {}}])
    run, folder = run_scripted(sadesim, doc, tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "criteria PASSED" in run.stdout, run.stdout
    plan = json.loads((folder / "plan.json").read_text())
    for drone, (lat, lon) in zip(plan["drones"], (east_home, west_home)):
        assert drone["home"]["global"]["altitudeMslM"] == pytest.approx(ground(lon, lat), abs=0.2), drone["home"]
    rows = list(csv.DictReader((folder / "trajectory.csv").open()))
    for drone, (lat, lon) in enumerate((east_home, west_home)):
        hovering = [r for r in rows if int(r["drone"]) == drone and 25.0 <= float(r["time_s"]) <= 30.0]
        assert hovering
        for r in hovering:
            assert float(r["height_agl_m"]) == pytest.approx(20.0, abs=1.0), r
            assert float(r["altitude_msl_m"]) == pytest.approx(ground(lon, lat) + 20.0, abs=1.2), r
    world = json.loads((folder / "world.json").read_text())
    assert world["groundMaxUpM"] - world["groundMinUpM"] > 40, "the slope spans the world square"


def test_the_jacksboro_example_follows_real_terrain(sadesim, venv_bin, helsinki, repo, tmp_path):  # noqa: F811
    """examples/maps/jacksboro.yaml over the elevation model its fetch script makes from
    matplotlib's sample data (a real 90 m DEM with 600 m of relief): the homes stand on the
    DEM's ground as GDAL reads it, the survey stays 25 m or more above the ground along its
    legs, and the criteria pass."""
    folder = tmp_path / "maps"
    folder.mkdir()
    for name in ("jacksboro.yaml", "fetch-data.sh"):
        (folder / name).write_text((repo / "examples" / "maps" / name).read_text())
    (folder / "Helsinki.osm.pbf").write_bytes(helsinki.read_bytes())  # present: not fetched again
    (folder / "gnss-2020-12-01.tle").write_text("")  # not needed here: not fetched
    subprocess.run(["bash", str(folder / "fetch-data.sh"), str(venv_bin / "python")], check=True)
    tif = folder / "jacksboro.tif"
    info = json.loads(subprocess.run(["gdalinfo", "-json", str(tif)], check=True, capture_output=True, text=True).stdout)
    assert info["size"] == [403, 344] and "4326" in info["coordinateSystem"]["wkt"].split("ID[")[-1]
    out = tmp_path / "runs"
    run = subprocess.run([sadesim, "run", str(folder / "jacksboro.yaml"), "--out", str(out), "-q", "--no-mavlink"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "criteria PASSED: 3 of 3" in run.stdout, run.stdout
    result = next(out.glob("jacksboro/*"))
    plan = json.loads((result / "plan.json").read_text())
    # GDAL's reading of the raster, interpolated bilinearly between pixel centres.
    asc = tmp_path / "jacksboro.asc"
    gdal("gdal_translate", "-q", "-of", "AAIGrid", str(tif), str(asc))
    lines = asc.read_text().splitlines()
    header = {k.lower(): float(v) for k, v in (line.split() for line in lines[:5])}
    grid = [[float(v) for v in line.split()] for line in lines[5:] if line.strip()]
    west, north = header["xllcorner"], header["yllcorner"] + header["nrows"] * header["cellsize"]

    def gdal_ground(lon, lat):
        x, y = (lon - west) / header["cellsize"] - 0.5, (north - lat) / header["cellsize"] - 0.5
        i, j = math.floor(x), math.floor(y)
        fx, fy = x - i, y - j
        return ((1 - fx) * (1 - fy) * grid[j][i] + fx * (1 - fy) * grid[j][i + 1]
                + (1 - fx) * fy * grid[j + 1][i] + fx * fy * grid[j + 1][i + 1])

    for drone in plan["drones"]:
        g = drone["home"]["global"]
        theirs = gdal_ground(g["longitudeDeg"], g["latitudeDeg"])
        # Resampled on the world's ground grid (about 6 m) from 90 m cells: within a metre.
        assert g["altitudeMslM"] == pytest.approx(theirs, abs=1.0), (g, theirs)
    rows = list(csv.DictReader((result / "trajectory.csv").open()))
    for drone in range(len(plan["drones"])):
        agl = [float(r["height_agl_m"]) for r in rows if int(r["drone"]) == drone]
        # From the first to the last moment above 35 m AGL (after the climb, before the
        # descent to land): never below 25 m over the slopes (the legs are planned 60 m up;
        # a drone climbs more slowly than it flies forward), never above the 120 m limit.
        above = [i for i, h in enumerate(agl) if h > 35.0]
        cruise = agl[above[0]:above[-1] + 1]
        assert len(cruise) > 100 and min(cruise) >= 25.0 and max(cruise) <= 120.0, (drone, min(cruise), max(cruise))
    world = json.loads((result / "world.json").read_text())
    assert world["groundMaxUpM"] - world["groundMinUpM"] > 500, "real relief"
