"""OpenFOAM fields in runs (`environment.wind.urban.model: openfoam`): a case computed
elsewhere is imported and flown, bad cases are refused naming the file and the problem, and
the asset phase runs Debian's OpenFOAM over a real Helsinki square and stores the field as
the built-in model's (wind.zarr, read with xarray)."""
import json
import re
import shutil
import subprocess

import numpy as np
import pytest
import xarray as xr
from mcap.reader import make_reader

from test_osm import helsinki  # noqa: F401  (the fixture)

# examples/maps/helsinki.yaml's origin; a 200 m square (extentM 100) around it.
ORIGIN = {"latitudeDeg": 60.1700, "longitudeDeg": 24.9470, "altitudeMslM": 10}
SPEED = 8.0


def scenario(extract, urban, seconds=40) -> dict:
    return {
        "apiVersion": "sadesim.io/v1alpha1", "kind": "SimulationRun", "metadata": {"name": "foam"},
        "spec": {
            "origin": ORIGIN, "duration": f"{seconds}s", "clock": {"mode": "asFastAsPossible"}, "seed": 3,
            "world": {"source": "osm", "osm": {"file": str(extract)}, "extentM": 100},
            "environment": {"wind": {"speedMps": SPEED, "directionFromDeg": 270, "urban": urban}},
            "fleet": [{
                "name": "probe", "count": 1, "airframe": "x500", "operator": "t",
                "homes": {"explicit": [{"latitudeDeg": 60.17008, "longitudeDeg": 24.94700}]},
                "altitude": {"maxAglM": 80},
                "mission": {"items": [{"takeoff": {"altitudeAglM": 60}}, {"loiter": {"holdS": 600}}]},
            }],
        },
    }


def write_case(folder, east=10.0, top=200.0, half=100.0, spacing=5.0, nan_at=None):
    """A case 'computed elsewhere': cell centres on a 5 m lattice over the square (the run's
    ENU), a uniform wind of `east` m/s blowing east (from 270°), in time directory 100."""
    time = folder / "100"
    time.mkdir(parents=True)
    axis = np.arange(-half + spacing / 2, half, spacing)
    ups = np.arange(spacing / 2, top, spacing)
    z, y, x = np.meshgrid(ups, axis, axis, indexing="ij")
    centres = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)

    def field(name, dims, rows):
        lines = [f"({a:.4f} {b:.4f} {c:.4f})" for a, b, c in rows]
        if nan_at is not None and name == "U":
            lines[nan_at] = "(nan 0 0)"
        header = (f"FoamFile\n{{\n    version 2.0;\n    format ascii;\n    class volVectorField;\n"
                  f"    object {name};\n}}\ndimensions {dims};\n")
        (time / name).write_text(header + f"internalField nonuniform List<vector>\n{len(lines)}\n(\n"
                                 + "\n".join(lines) + "\n);\nboundaryField\n{\n}\n")

    field("C", "[0 1 0 0 0 0 0]", centres)
    field("U", "[0 1 -1 0 0 0 0]", np.tile([east, 0.0, 0.0], (len(centres), 1)))
    return folder


def run(sadesim, doc, tmp_path, *flags):
    path = tmp_path / "foam.yaml"
    path.write_text(json.dumps(doc))
    out = tmp_path / "runs"
    return subprocess.run([sadesim, "run", str(path), "--out", str(out), "-q", "--no-mavlink",
                           "--no-asset-cache", *flags], capture_output=True, text=True), out


def test_an_imported_case_is_the_wind_the_drone_flies_in(sadesim, helsinki, tmp_path):  # noqa: F811
    """A uniform 10 m/s case: the field is 1.0 x the reference wind wherever the air is free,
    so the hovering drone meets exactly the scenario's 8 m/s (no log profile: the case has
    none), where the built-in model would give it the profile's 1.78 x at 60 m."""
    case = write_case(tmp_path / "case")
    doc = scenario(helsinki, {"model": "openfoam",
                              "case": {"dir": str(case), "directionFromDeg": 270, "referenceSpeedMps": 10}})
    done, out = run(sadesim, doc, tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    folder = next(out.glob("foam/*"))
    speeds = []
    with open(folder / "recording.mcap", "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=["/drones/probe-0/wind"]):
            if message.log_time >= 20e9:
                v = json.loads(message.data)["velocity_enu_mps"]
                speeds.append((v["x"], v["y"]))
    mean = np.mean(speeds, axis=0)
    assert mean[0] == pytest.approx(SPEED, rel=0.02) and abs(mean[1]) < 0.05, mean


@pytest.mark.parametrize("damage, message", [
    ("nan", r"100/U:\d+: entry 17 \(0-based\) of the internal field has a non-finite component"),
    ("half", r"100/C: the case does not cover the world's wind grid"),
    ("no C", r"100/C is missing: the cell centres of time 100; run `postProcess -func writeCellCentres"),
])
def test_a_bad_case_is_refused_naming_the_file(sadesim, helsinki, tmp_path, damage, message):  # noqa: F811
    case = tmp_path / "case"
    if damage == "nan":
        write_case(case, nan_at=17)
    elif damage == "half":
        write_case(case, half=50.0)
    else:
        write_case(case)
        (case / "100" / "C").unlink()
    doc = scenario(helsinki, {"model": "openfoam",
                              "case": {"dir": str(case), "directionFromDeg": 270, "referenceSpeedMps": 10}})
    done, out = run(sadesim, doc, tmp_path)
    assert done.returncode != 0
    assert re.search(message, done.stdout + done.stderr), done.stdout + done.stderr


@pytest.mark.skipif(shutil.which("simpleFoam") is None or shutil.which("snappyHexMesh") is None,
                    reason="OpenFOAM is not installed: bash tests/install-tools.sh installs it")
def test_the_asset_phase_runs_openfoam_over_the_map_and_stores_the_field(sadesim, helsinki, tmp_path):  # noqa: F811
    """`sadesim assets build` with model openfoam: blockMesh, snappyHexMesh on the square's
    buildings, simpleFoam; the stored field holds the run direction's sector (wind from
    270°), zero wind in the buildings, flow slowed among them and the open inflow above."""
    doc = scenario(helsinki, {"model": "openfoam"})
    path = tmp_path / "foam.yaml"
    path.write_text(json.dumps(doc))
    cache = f"file://{tmp_path / 'cache'}"
    built = subprocess.run([sadesim, "assets", "build", str(path), "--asset-cache", cache, "-q"],
                           capture_output=True, text=True)
    assert built.returncode == 0, built.stdout + built.stderr
    entry = re.search(r"urban wind field computed and stored: file://(\S+)", built.stdout)
    assert entry, built.stdout
    field = xr.open_zarr(f"{entry.group(1)}/wind.zarr")
    assert field.attrs["model"] == "openfoam"
    assert list(field["direction_from_deg"].values) == [270.0]
    solid = field["solid"].values.astype(bool)
    east = field["east"].isel(sector=0).values
    assert np.all(east[solid] == 0)
    # Low among the buildings, near the reference profile well above them.
    low, high = east[1][~solid[1]], east[-2][~solid[-2]]
    print(json.dumps({"low_mean": float(low.mean()), "high_mean": float(high.mean())}))
    assert low.mean() < 0.8 * high.mean()
    # The run flies in it, loaded from the cache.
    again = subprocess.run([sadesim, "run", str(path), "--out", str(tmp_path / "runs"), "-q", "--no-mavlink",
                            "--asset-cache", cache], capture_output=True, text=True)
    assert again.returncode == 0, again.stdout + again.stderr
    shutil.rmtree(tmp_path / "cache", ignore_errors=True)
