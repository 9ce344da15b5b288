"""The DEM reader (`sadesim dem`, `sadesim_world::dem`) on GeoTIFFs written by GDAL
(Debian's `gdal-bin`, installed by tests/install-tools.sh), checked against GDAL's own readers: `gdallocationinfo` for the
values, `gdaltransform` (PROJ) for the UTM projection.
"""
import json
import math
import subprocess

import pytest

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


def test_broken_dems_are_one_line_errors(sadesim, tmp_path):
    asc = tmp_path / "dem.asc"
    ascii_grid(asc, surface)
    plain = tmp_path / "plain.tif"
    gdal("gdal_translate", "-q", str(asc), str(plain))  # no CRS
    mercator = tmp_path / "mercator.tif"
    gdal("gdalwarp", "-q", "-s_srs", "EPSG:4326", "-t_srs", "EPSG:3857", str(asc), str(mercator))
    lzw = tmp_path / "lzw.tif"
    gdal("gdal_translate", "-q", "-a_srs", "EPSG:4326", "-co", "COMPRESS=LZW", str(asc), str(lzw))
    good = tmp_path / "good.tif"
    gdal("gdal_translate", "-q", "-a_srs", "EPSG:4326", str(asc), str(good))
    cut = tmp_path / "cut.tif"
    cut.write_bytes(good.read_bytes()[:4000])
    for dem, extent, expected in [
        (plain, 1000, "no georeferencing"),
        (mercator, 1000, "EPSG:3857"),
        (lzw, 1000, "LZW compression"),
        (cut, 1000, "truncated"),
        (good, 3000, "does not cover world.extentM 3000 m"),
    ]:
        run = subprocess.run([sadesim, "dem", str(dem), "--origin", f"{ORIGIN[0]},{ORIGIN[1]}", "--extent-m", str(extent)],
                             capture_output=True, text=True)
        assert run.returncode == 2, run
        lines = run.stderr.strip().splitlines()
        assert len(lines) == 1 and expected in lines[0], run.stderr
