"""GNSS geometry (`sadesim gnss sky`, crate sadesim-gnss) against software no one here wrote:
look angles against Skyfield (its SGP4 and Earth rotation) for the same orbit file at three
epochs, and dilution of precision against gnss_lib_py for the same satellite set.

The orbit file is the public catalogue of 2020-12-01 that Debian's `rtklib` package ships
(`/usr/share/rtklib/TLE_20201201txt.txt`, unpacked into `.tools/rtklib` by
tests/install-tools.sh; not committed), from which the navigation satellites are taken by
name (NAVSTAR, GALILEO, ...).
"""
import json
import subprocess

import numpy as np
import pytest
from gnss_lib_py.navdata.navdata import NavData
from gnss_lib_py.utils.dop import calculate_dop
from skyfield.api import load, wgs84

RECEIVER = (60.1699, 24.9384, 25.0)  # Helsinki, metres above the ellipsoid
EPOCHS = ["2020-12-01T00:00:00Z", "2020-12-01T07:20:00Z", "2020-12-02T15:45:30Z"]


@pytest.fixture(scope="module")
def orbits(repo):
    path = repo / ".tools" / "rtklib" / "usr" / "share" / "rtklib" / "TLE_20201201txt.txt"
    assert path.exists(), "run tests/install-tools.sh (it unpacks Debian's rtklib package)"
    return path


def sky(sadesim, orbits, time, mask=0.0):
    done = subprocess.run([sadesim, "gnss", "sky", str(orbits), "--at", ",".join(map(str, RECEIVER)),
                           "--time", time, "--mask-deg", str(mask), "--json"], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    return json.loads(done.stdout)


@pytest.mark.parametrize("time", EPOCHS)
def test_look_angles_agree_with_skyfield(sadesim, orbits, time):
    ours = sky(sadesim, orbits, time)
    assert len(ours["satellites"]) >= 20, "GPS and Galileo satellites above the horizon"
    systems = {s["system"] for s in ours["satellites"]}
    assert {"gps", "galileo"} <= systems, systems
    ts = load.timescale(builtin=True)
    t = ts.from_datetime(__import__("datetime").datetime.fromisoformat(time.replace("Z", "+00:00")))
    by_id = {s.model.satnum: s for s in load.tle_file(str(orbits))}
    topos = wgs84.latlon(*RECEIVER[:2], elevation_m=RECEIVER[2])
    worst = 0.0
    for s in ours["satellites"]:
        alt, az, _ = (by_id[s["noradId"]] - topos).at(t).altaz()
        d_el = abs(s["elevationDeg"] - alt.degrees)
        d_az = abs((s["azimuthDeg"] - az.degrees + 180.0) % 360.0 - 180.0) * np.cos(np.radians(alt.degrees))
        worst = max(worst, d_el, d_az)
        assert d_el < 0.1 and d_az < 0.1, (s["name"], s["elevationDeg"], alt.degrees, s["azimuthDeg"], az.degrees)
    print(f"{time}: {len(ours['satellites'])} satellites, largest difference {worst:.4f} deg")


def test_dop_agrees_with_gnss_lib_py(sadesim, orbits):
    for time in EPOCHS:
        ours = sky(sadesim, orbits, time, mask=10.0)
        sats = ours["satellites"]
        nav = NavData()
        nav["el_sv_deg"] = np.array([s["elevationDeg"] for s in sats])
        nav["az_sv_deg"] = np.array([s["azimuthDeg"] for s in sats])
        theirs = calculate_dop(nav)
        for key in ["GDOP", "PDOP", "HDOP", "VDOP", "TDOP"]:
            mine = ours["dop"][key.lower()]
            assert mine == pytest.approx(theirs[key], rel=0.01), (time, key, mine, theirs[key])


def test_an_orbit_file_far_from_the_time_is_warned_about(sadesim, orbits):
    done = subprocess.run([sadesim, "gnss", "sky", str(orbits), "--at", "60.17,24.94", "--time",
                           "2026-12-03T12:00:00Z"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "warning:" in done.stderr and "days from 2026-12-03T12:00:00Z" in done.stderr, done.stderr


def test_a_file_that_is_not_an_orbit_file_is_one_line_naming_the_line(sadesim, tmp_path):
    bad = tmp_path / "gnss.tle"
    bad.write_text("0 NAVSTAR 43 (USA 132)\n1 24876U 97035A   20334.96836884 +.00000096 +00000-0 +00000-0 0  9991\n"
                   "2 24876 055.4606 177.6943 0046391 058.6753 301.8606 02.00562032171136\n")
    done = subprocess.run([sadesim, "gnss", "sky", str(bad), "--at", "60.17,24.94", "--time", "2020-12-01T00:00:00Z"],
                          capture_output=True, text=True)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "gnss.tle: line 2:" in lines[0] and "checksum" in lines[0].lower(), done.stderr
