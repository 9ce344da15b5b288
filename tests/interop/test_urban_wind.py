"""Urban wind on the real Helsinki map (examples/maps/helsinki-wind.yaml), read with the tools
a user would use on our output: the field the asset cache stores opened with xarray (its
Zarr group), the wind each drone met read from recording.mcap with the `mcap` reader, and
the wind slice of `sadesim assets show` decoded with Pillow."""
import json
import re
import shutil
import subprocess

import numpy as np
import pytest
import xarray as xr
from mcap.reader import make_reader
from PIL import Image

from test_osm import helsinki  # noqa: F401  (the fixture)

EXAMPLE = "helsinki-wind.yaml"


@pytest.fixture(scope="module")
def maps(repo, helsinki, tmp_path_factory):  # noqa: F811
    """The example beside the Helsinki extract, and an asset cache folder."""
    folder = tmp_path_factory.mktemp("maps")
    shutil.copy(repo / "examples" / "maps" / EXAMPLE, folder / EXAMPLE)
    (folder / "Helsinki.osm.pbf").write_bytes(helsinki.read_bytes())
    return folder


@pytest.fixture(scope="module")
def built(sadesim, maps):
    """`sadesim assets build` of the example: the wind entry's folder and the output."""
    cache = f"file://{maps / 'cache'}"
    done = subprocess.run([sadesim, "assets", "build", str(maps / EXAMPLE), "--asset-cache", cache, "-q"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    entry = re.search(r"urban wind field computed and stored: file://(\S+)", done.stdout)
    assert entry, done.stdout
    return {"entry": entry.group(1), "stdout": done.stdout, "cache": cache}


def test_the_stored_field_opens_in_xarray_with_its_grid_and_every_sector(built):
    field = xr.open_zarr(f"{built['entry']}/wind.zarr")
    attrs = field.attrs
    assert attrs["model"] == "diagnostic" and attrs["sectorCount"] == 8
    assert field["east"].dims == ("sector", "up", "north", "east")
    assert list(field["direction_from_deg"].values) == [0, 45, 90, 135, 180, 225, 270, 315]
    solid = field["solid"].values.astype(bool)
    east, north, up = (field[c].values for c in ("east", "north", "up"))
    # No wind inside buildings or under the ground; finite everywhere.
    assert np.all(east[:, solid] == 0) and np.all(north[:, solid] == 0) and np.all(up[:, solid] == 0)
    assert np.isfinite(east).all() and np.isfinite(north).all()
    # Every sector conserves mass to the solver's tolerance.
    assert max(s["residual"] for s in attrs["sectors"]) < 1e-6
    h = attrs["spacingM"]
    assert h == 5.0
    # The lowest free cells of open ground hold the profile's factor for their height: the
    # most common horizontal speed at that level is the profile's (the rest are slowed in
    # wakes or channelled along streets, faster than the profile).
    k = 1  # 7.5 m above the grid's floor
    profile = np.log(((k + 0.5) * h) / 1.0) / np.log(10.0)
    free = ~solid[k]
    sector = field.isel(sector=6)  # wind from 270°: blows east
    speed = np.hypot(sector["east"].values[k], sector["north"].values[k])[free]
    counts, edges = np.histogram(speed, bins=np.arange(0.0, 2.0 * profile, 0.0125 * profile))
    mode = (edges[counts.argmax()] + edges[counts.argmax() + 1]) / 2
    assert mode == pytest.approx(profile, rel=0.05)
    assert np.mean(np.abs(speed - profile) < 0.02 * profile) > 0.05


def test_a_second_build_finds_the_field_in_the_cache(sadesim, maps, built):
    again = subprocess.run([sadesim, "assets", "build", str(maps / EXAMPLE), "--asset-cache", built["cache"], "-q"],
                           capture_output=True, text=True)
    assert again.returncode == 0, again.stdout + again.stderr
    assert f"urban wind field found in the asset cache: file://{built['entry']}" in again.stdout, again.stdout


def test_the_example_drones_meet_the_wind_of_where_they_fly(sadesim, maps, built, tmp_path):
    """The lee drone meets a fraction of the open drone's wind at the same height; the drone
    flying Esplanadi, along the wind, meets nearly the open wind; summary.json, the report
    and the MCAP agree."""
    out = tmp_path / "runs"
    run = subprocess.run([sadesim, "run", str(maps / EXAMPLE), "--out", str(out), "-q", "--no-mavlink",
                          "--asset-cache", built["cache"]], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "criteria PASSED" in run.stdout, run.stdout
    folder = next(out.glob("helsinki-wind/*"))
    # Horizontal wind per drone while airborne, from the recording.
    speeds: dict[str, list[tuple[int, float]]] = {}
    with open(folder / "recording.mcap", "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=None):
            if channel.topic.startswith("/drones/") and channel.topic.endswith("/wind"):
                v = json.loads(message.data)["velocity_enu_mps"]
                speeds.setdefault(channel.topic.split("/")[2], []).append((message.log_time, np.hypot(v["x"], v["y"])))
    summary = {d["name"]: d["wind"] for d in json.loads((folder / "summary.json").read_text())["perDrone"]}
    mean = {}
    for name, rows in speeds.items():
        # The hold: from 30 s (climb over) to 110 s (before the landing).
        hold = [v for t, v in rows if 30e9 <= t <= 110e9]
        mean[name] = float(np.mean(hold))
    print(json.dumps({"mcap_hold_mean": mean, "summary": summary}, indent=1))
    lee, open_, esplanadi = mean["lee-0"], mean["open-0"], mean["esplanadi-0"]
    assert lee < 0.4 * open_, (lee, open_)
    assert esplanadi > 0.75 * open_, (esplanadi, open_)
    # summary.json's in-flight means tell the same story.
    assert summary["lee-0"]["meanMps"] < 0.4 * summary["open-0"]["meanMps"]
    report = (folder / "report.html").read_text()
    assert "wind met (mean / max)" in report
    assert f"{summary['lee-0']['meanMps']:.1f} / {summary['lee-0']['maxMps']:.1f} m/s" in report


def test_the_wind_slice_is_a_picture_of_the_field(sadesim, maps, built, tmp_path):
    png = tmp_path / "slice.png"
    shown = subprocess.run([sadesim, "assets", "show", str(maps / EXAMPLE), "--asset-cache", built["cache"],
                            "--png", str(tmp_path / "world.png"), "--wind-slice-agl", "20", "--wind-png", str(png),
                            "-q"], capture_output=True, text=True)
    assert shown.returncode == 0, shown.stdout + shown.stderr
    line = re.search(r"wind slice 20 m above the ground: \S+ \((\d+) columns: (\d+) % below half", shown.stdout)
    assert line, shown.stdout
    assert int(line.group(1)) > 5000 and 5 < int(line.group(2)) < 80
    image = Image.open(png).convert("RGB")
    assert image.size[0] == 1400
    pixels = np.asarray(image).reshape(-1, 3)
    # Both ends of the palette are drawn: sheltered (dark blue #2166ac) and open (#f7f7f7).
    assert (np.abs(pixels - [0x21, 0x66, 0xac]).sum(axis=1) < 10).sum() > 1000
    assert (np.abs(pixels - [0xf7, 0xf7, 0xf7]).sum(axis=1) < 6).sum() > 1000
    # Without wind in the scenario there is nothing to draw: a clear error.
    calm = maps / "calm.yaml"
    calm.write_text(re.sub(r"  environment:\n(    .*\n)+", "", (maps / EXAMPLE).read_text()))
    refused = subprocess.run([sadesim, "assets", "show", str(calm), "--asset-cache", built["cache"], "--png",
                              str(tmp_path / "w.png"), "--wind-slice-agl", "20", "-q"], capture_output=True, text=True)
    assert refused.returncode != 0
    assert "has no spec.environment.wind" in refused.stdout + refused.stderr
