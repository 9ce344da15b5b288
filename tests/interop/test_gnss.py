"""GNSS geometry (`sadesim gnss sky`, crate sadesim-gnss) against software no one here wrote:
look angles against Skyfield (its SGP4 and Earth rotation) for the same orbit file at three
epochs, and dilution of precision against gnss_lib_py for the same satellite set. The same
element sets as OMM (written by the `sgp4` package's exporter in KVN, XML, JSON and CSV, read
back by Skyfield through `sgp4.omm` where it has a reader) give the same sky.

The orbit file is the public catalogue of 2020-12-01 that Debian's `rtklib` package ships
(`/usr/share/rtklib/TLE_20201201txt.txt`, unpacked into `.tools/rtklib` by
tests/install-tools.sh; not committed), from which the navigation satellites are taken by
name (NAVSTAR, GALILEO, ...).
"""
import csv
import io
import json
import subprocess
from xml.sax.saxutils import escape

import numpy as np
import pytest
from gnss_lib_py.navdata.navdata import NavData
from gnss_lib_py.utils.dop import calculate_dop
from sgp4 import exporter, omm
from skyfield.api import EarthSatellite, load, wgs84

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


def omm_text(records, encoding):
    """`records` (OMM fields as `sgp4.exporter.export_omm` gives them) in `encoding`, shaped
    as CelesTrak serves each (FORMAT=kvn, xml, json, csv)."""
    if encoding == "json":
        return json.dumps(records, indent=1)
    if encoding == "csv":
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=list(records[0]))
        writer.writeheader()
        writer.writerows(records)
        return out.getvalue()
    if encoding == "kvn":
        return "".join("CCSDS_OMM_VERS = 2.0\nCOMMENT exported by sgp4\n"
                       + "".join(f"{k} = {v}\n" for k, v in r.items()) for r in records)
    metadata = ["OBJECT_NAME", "OBJECT_ID", "CENTER_NAME", "REF_FRAME", "TIME_SYSTEM", "MEAN_ELEMENT_THEORY"]
    mean = ["EPOCH", "MEAN_MOTION", "ECCENTRICITY", "INCLINATION", "RA_OF_ASC_NODE", "ARG_OF_PERICENTER",
            "MEAN_ANOMALY"]

    def tags(r, keys):
        return "".join(f"<{k}>{escape(str(r[k]))}</{k}>" for k in keys)

    body = "".join(
        '<omm id="CCSDS_OMM_VERS" version="2.0"><header><CREATION_DATE/><ORIGINATOR/></header><body><segment>\n'
        f"<metadata>{tags(r, metadata)}</metadata>\n<data><meanElements>{tags(r, mean)}</meanElements>\n"
        f"<tleParameters>{tags(r, [k for k in r if k not in metadata + mean])}</tleParameters></data>\n"
        "</segment></body></omm>\n" for r in records)
    return f'<?xml version="1.0" encoding="UTF-8"?>\n<ndm>\n{body}</ndm>\n'


def omm_records(orbits):
    """The catalogue's element sets as OMM fields (`sgp4.exporter.export_omm`), less the few
    objects without an international designator, which the exporter cannot write (none is a
    navigation satellite)."""
    return [exporter.export_omm(s.model, s.name) for s in load.tle_file(str(orbits)) if s.model.intldesg.strip()]


@pytest.mark.parametrize("encoding", ["kvn", "xml", "json", "csv"])
def test_the_same_element_sets_as_omm_give_the_same_sky(sadesim, orbits, tmp_path, encoding):
    ts = load.timescale(builtin=True)
    records = omm_records(orbits)
    path = tmp_path / f"gnss.{encoding}"
    path.write_text(omm_text(records, encoding))
    time = EPOCHS[1]
    from_tle, from_omm = sky(sadesim, orbits, time), sky(sadesim, path, time)
    assert len(from_omm["satellites"]) == len(from_tle["satellites"]) >= 20
    for a, b in zip(from_tle["satellites"], from_omm["satellites"]):
        assert (a["name"], a["noradId"], a["system"]) == (b["name"], b["noradId"], b["system"])
        # The exporter writes the epoch to the microsecond and the angles in full: metres apart.
        assert abs(a["elevationDeg"] - b["elevationDeg"]) < 1e-5 and abs(a["rangeM"] - b["rangeM"]) < 5.0, (a, b)
    assert from_omm["dop"]["pdop"] == pytest.approx(from_tle["dop"]["pdop"], rel=1e-6)
    if encoding in ("xml", "csv"):
        # Skyfield reads the same file through sgp4's own OMM readers.
        with open(path) as f:
            fields = list(omm.parse_xml(f) if encoding == "xml" else omm.parse_csv(f))
        theirs = {int(r["NORAD_CAT_ID"]): EarthSatellite.from_omm(ts, r) for r in fields}
        t = ts.from_datetime(__import__("datetime").datetime.fromisoformat(time.replace("Z", "+00:00")))
        topos = wgs84.latlon(*RECEIVER[:2], elevation_m=RECEIVER[2])
        for s in from_omm["satellites"]:
            alt, az, _ = (theirs[s["noradId"]] - topos).at(t).altaz()
            d_az = abs((s["azimuthDeg"] - az.degrees + 180.0) % 360.0 - 180.0) * np.cos(np.radians(alt.degrees))
            assert abs(s["elevationDeg"] - alt.degrees) < 0.1 and d_az < 0.1, (s, alt.degrees, az.degrees)


def test_an_omm_set_of_another_theory_is_refused_naming_the_key(sadesim, orbits, tmp_path):
    records = omm_records(orbits)
    navstar = next(i for i, r in enumerate(records) if r["OBJECT_NAME"].startswith("NAVSTAR"))
    records[navstar]["MEAN_ELEMENT_THEORY"] = "SGP4-XP"
    path = tmp_path / "gnss.json"
    path.write_text(omm_text(records, "json"))
    done = subprocess.run([sadesim, "gnss", "sky", str(path), "--at", "60.17,24.94", "--time", EPOCHS[0]],
                          capture_output=True, text=True)
    assert done.returncode == 2
    name = records[navstar]["OBJECT_NAME"]
    assert done.stderr.strip().splitlines() == [
        f'error: {path}: object {navstar + 1} of the JSON array ({name}): MEAN_ELEMENT_THEORY: "SGP4-XP" is not '
        "supported: sadesim propagates SGP4 elements (SGP4 or SGP/SGP4)"], done.stderr
