"""The per-drone PX4 ULog files (`ulog/<drone>.ulg`) read with pyulog, PX4's own reader
(Flight Review and PlotJuggler go through the same format).

One scripted run (2 drones, 40 s simulated, as fast as possible, no MAVLink): takeoff,
one waypoint, land. Checks topic names and fields, counts = duration x rate (+-1),
monotonic timestamps, ground truth against trajectory.csv (within a few cm), the
estimator (within a few m), battery, flight modes, logged messages, and pyulog's CLI tools.
"""
import csv
import json
import math
import pathlib
import subprocess

import pytest
import yaml
from pyulog import ULog

from simrun import EARTH_RADIUS_M, ORIGIN, PARK

HOMES = [
    {"latitudeDeg": 41.8826, "longitudeDeg": -87.6225},
    {"latitudeDeg": 41.8822, "longitudeDeg": -87.6230},
]
WAYPOINT = {"latitudeDeg": 41.8830, "longitudeDeg": -87.6220, "altitudeAglM": 10}
RATES = {"groundTruthHz": 100, "estimatorHz": 50, "actuatorsHz": 25, "statusHz": 5}
GNSS_HZ = 5
# WGS84 first eccentricity squared.
WGS84_E2 = 6.69437999014e-3

# PX4 NAVIGATION_STATE_*.
NAV_MISSION, NAV_LOITER, NAV_LAND = 3, 4, 18
# PX4 vehicle_status ARMING_STATE_*.
DISARMED, ARMED = 1, 2

# Fields our tools rely on, per topic (PX4 names).
FIELDS = {
    "vehicle_local_position": ["timestamp", "x", "y", "z", "vx", "vy", "vz", "ref_lat", "ref_lon", "ref_alt",
                               "xy_valid", "z_valid", "eph", "epv", "heading"],
    "vehicle_global_position": ["timestamp", "lat", "lon", "alt", "eph", "epv"],
    "vehicle_attitude": ["timestamp", "q[0]", "q[1]", "q[2]", "q[3]"],
    "sensor_gps": ["timestamp", "latitude_deg", "longitude_deg", "altitude_msl_m", "fix_type", "satellites_used",
                   "eph", "epv", "hdop", "vdop", "vel_n_m_s", "vel_e_m_s", "vel_d_m_s"],
    "battery_status": ["timestamp", "voltage_v", "current_a", "discharged_mah", "remaining"],
    "vehicle_status": ["timestamp", "arming_state", "nav_state"],
    "actuator_outputs": ["timestamp", "noutputs"] + [f"output[{i}]" for i in range(16)],
}
FIELDS["vehicle_local_position_groundtruth"] = FIELDS["vehicle_local_position"]
FIELDS["vehicle_global_position_groundtruth"] = FIELDS["vehicle_global_position"]
FIELDS["vehicle_attitude_groundtruth"] = FIELDS["vehicle_attitude"]
FIELDS["vehicle_gps_position"] = FIELDS["sensor_gps"]


def scenario() -> dict:
    return {
        "apiVersion": "sadesim.io/v1alpha1",
        "kind": "SimulationRun",
        "metadata": {"name": "ulog-test"},
        "spec": {
            "origin": ORIGIN,
            "duration": "40s",
            "clock": {"mode": "asFastAsPossible"},
            "seed": 3,
            "world": {"openAreas": [{"name": "park", "center": PARK, "radiusM": 250}]},
            "environment": {"gnss": {"rateHz": GNSS_HZ}},
            "recording": {"mcap": False, "ulog": True, "rates": RATES},
            "fleet": [{
                "name": "pair",
                "count": 2,
                "airframe": "x500",
                "operator": "ulog-tests",
                "homes": {"explicit": HOMES},
                "altitude": {"maxAglM": 60},
                "mission": {
                    "speedMps": 8,
                    "items": [{"takeoff": {"altitudeAglM": 10}}, {"waypoint": WAYPOINT}, {"land": {}}],
                },
            }],
        },
    }


@pytest.fixture(scope="module")
def run(sadesim, tmp_path_factory) -> pathlib.Path:
    tmp = tmp_path_factory.mktemp("ulog")
    path = tmp / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario()))
    out = subprocess.run([sadesim, "run", str(path), "--quiet", "--no-mavlink", "--out", str(tmp / "runs")],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    return pathlib.Path(next(l for l in out.stdout.splitlines() if "output:" in l).split("output: ")[1])


@pytest.fixture(scope="module")
def sim_time_s(run) -> float:
    return json.loads((run / "summary.json").read_text())["simTimeS"]


@pytest.fixture(scope="module")
def logs(run) -> dict:
    """Drone name -> parsed ULog."""
    files = sorted((run / "ulog").glob("*.ulg"))
    assert [f.name for f in files] == ["pair-0.ulg", "pair-1.ulg"]
    return {f.stem: ULog(str(f)) for f in files}


@pytest.fixture(scope="module")
def trajectory(run) -> dict:
    """Drone name -> {round(time_s * 1e6): row} (ground truth at 10 Hz)."""
    rows: dict = {}
    with open(run / "trajectory.csv", newline="") as f:
        for row in csv.DictReader(f):
            rows.setdefault(row["name"], {})[round(float(row["time_s"]) * 1e6)] = row
    return rows


def data(ulog: ULog, topic: str):
    return ulog.get_dataset(topic).data


def by_time(ulog: ULog, topic: str) -> dict:
    """{timestamp_us: sample as dict}."""
    d = data(ulog, topic)
    return {int(t): {k: v[i] for k, v in d.items()} for i, t in enumerate(d["timestamp"])}


def ned_from(ref_lat: float, ref_lon: float, ref_alt: float, row: dict) -> tuple[float, float, float]:
    """A trajectory row's position in NED metres from the reference point: flat earth with
    WGS84's local radii of curvature (meridian M for north, prime vertical N for east),
    < 1 cm over this flight."""
    s2 = math.sin(math.radians(ref_lat)) ** 2
    n_radius = EARTH_RADIUS_M / math.sqrt(1 - WGS84_E2 * s2)
    m_radius = EARTH_RADIUS_M * (1 - WGS84_E2) / (1 - WGS84_E2 * s2) ** 1.5
    north = math.radians(float(row["latitude_deg"]) - ref_lat) * m_radius
    east = math.radians(float(row["longitude_deg"]) - ref_lon) * n_radius * math.cos(math.radians(ref_lat))
    return north, east, -(float(row["altitude_msl_m"]) - ref_alt)


def enu_from_origin(row: dict) -> tuple[float, float, float]:
    return float(row["east_m"]), float(row["north_m"]), float(row["up_m"])


def test_files_have_px4_definitions_info_and_parameters(logs):
    for name, ulog in logs.items():
        topics = {d.name for d in ulog.data_list}
        assert topics == set(FIELDS), topics
        for topic, fields in FIELDS.items():
            missing = set(fields) - set(data(ulog, topic))
            assert not missing, f"{name} {topic}: missing {missing}"
        assert ulog.msg_info_dict["sys_name"] == "SADE-SIM"
        assert ulog.msg_info_dict["sys_uuid"] == f"ulog-test/{name}"
        assert ulog.msg_info_dict["ver_hw"] == "SADESIM_X500"
        assert ulog.msg_info_dict["time_ref_utc"] == 0
        assert ulog.initial_parameters["SYS_AUTOSTART"] == 4001
        assert ulog.initial_parameters["MPC_XY_CRUISE"] == pytest.approx(8.0)
        assert not ulog.file_corruption
        assert not ulog.dropouts


def test_counts_are_duration_times_rate(logs, sim_time_s):
    for name, ulog in logs.items():
        gps = data(ulog, "sensor_gps")
        first_fix_s = min(t for t, fix in zip(gps["timestamp_sample"], gps["fix_type"]) if fix >= 3) * 1e-6
        expected = {
            # Ground truth at the estimator's rate (as PX4 SITL), groundTruthHz is MCAP's.
            "vehicle_local_position_groundtruth": sim_time_s * RATES["estimatorHz"],
            "vehicle_global_position_groundtruth": sim_time_s * RATES["estimatorHz"],
            "vehicle_attitude_groundtruth": sim_time_s * RATES["estimatorHz"],
            # The estimator publishes from its first GNSS fix on, as PX4's EKF.
            "vehicle_local_position": (sim_time_s - first_fix_s) * RATES["estimatorHz"],
            "vehicle_global_position": (sim_time_s - first_fix_s) * RATES["estimatorHz"],
            "vehicle_attitude": (sim_time_s - first_fix_s) * RATES["estimatorHz"],
            "actuator_outputs": sim_time_s * RATES["actuatorsHz"],
            "battery_status": sim_time_s * RATES["statusHz"],
            "vehicle_status": sim_time_s * RATES["statusHz"],
            "sensor_gps": sim_time_s * GNSS_HZ,
            "vehicle_gps_position": sim_time_s * GNSS_HZ,
        }
        for topic, n in expected.items():
            count = len(data(ulog, topic)["timestamp"])
            assert abs(count - n) <= 1, f"{name} {topic}: {count} samples, expected {n:.0f} +- 1"


def test_timestamps_are_positive_and_monotonic(logs, sim_time_s):
    for name, ulog in logs.items():
        for d in ulog.data_list:
            t = d.data["timestamp"]
            assert t[0] > 0, f"{name} {d.name}"
            assert all(b > a for a, b in zip(t, t[1:])), f"{name} {d.name}: not strictly increasing"
            assert t[-1] <= round(sim_time_s * 1e6)
        logged = [m.timestamp for m in ulog.logged_messages]
        assert logged and all(b >= a for a, b in zip(logged, logged[1:]))
        assert ulog.last_timestamp <= round(sim_time_s * 1e6)


def test_ground_truth_matches_the_trajectory_within_centimetres(logs, trajectory):
    for name, ulog in logs.items():
        local = by_time(ulog, "vehicle_local_position_groundtruth")
        glob = by_time(ulog, "vehicle_global_position_groundtruth")
        att = by_time(ulog, "vehicle_attitude_groundtruth")
        first = next(iter(local.values()))
        ref = (first["ref_lat"], first["ref_lon"], first["ref_alt"])
        # The local origin is where the drone booted: its home, on the ground.
        home = HOMES[int(name[-1])]
        assert ref[0] == pytest.approx(home["latitudeDeg"], abs=1e-6)
        assert ref[1] == pytest.approx(home["longitudeDeg"], abs=1e-6)
        rows = trajectory[name]
        common = sorted(set(rows) & set(local))
        assert len(common) >= 390, len(common)
        origin_enu = None
        for t in common:
            row, s = rows[t], local[t]
            # Against the trajectory's geodetic columns, through the logged reference point.
            n, e, d = ned_from(*ref, row)
            assert (s["x"], s["y"], s["z"]) == pytest.approx((n, e, d), abs=0.05), f"{name} at {t} us"
            # Against its ENU columns: a constant offset (the drone's origin), axes swapped.
            east, north, up = enu_from_origin(row)
            offset = (north - s["x"], east - s["y"], up + s["z"])
            origin_enu = origin_enu or offset
            assert offset == pytest.approx(origin_enu, abs=0.005), f"{name} at {t} us"
            vel = (float(row["vel_north_mps"]), float(row["vel_east_mps"]), -float(row["vel_up_mps"]))
            assert (s["vx"], s["vy"], s["vz"]) == pytest.approx(vel, abs=0.002)
            g = glob[t]
            assert g["lat"] == pytest.approx(float(row["latitude_deg"]), abs=2e-7)
            assert g["lon"] == pytest.approx(float(row["longitude_deg"]), abs=2e-7)
            assert g["alt"] == pytest.approx(float(row["altitude_msl_m"]), abs=0.01)
            # FRD -> NED heading (from north, clockwise) = 90 deg - ENU yaw.
            q = [att[t][f"q[{i}]"] for i in range(4)]
            heading = math.degrees(math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2)))
            expected = 90.0 - float(row["yaw_deg"])
            assert (heading - expected + 180) % 360 - 180 == pytest.approx(0, abs=0.05), f"{name} at {t} us"
            assert sum(c * c for c in q) == pytest.approx(1.0, abs=1e-5)
        assert origin_enu[2] == pytest.approx(float(rows[common[0]]["up_m"]), abs=0.5)


def test_estimator_stays_within_metres_of_the_truth(logs, trajectory):
    for name, ulog in logs.items():
        est = by_time(ulog, "vehicle_local_position")
        truth = by_time(ulog, "vehicle_local_position_groundtruth")
        common = sorted(set(est) & set(truth))
        assert len(common) >= 1900
        for t in common:
            e, g = est[t], truth[t]
            assert e["xy_valid"] and e["z_valid"]
            assert math.hypot(e["x"] - g["x"], e["y"] - g["y"]) < 3.0, f"{name} at {t} us"
            assert abs(e["z"] - g["z"]) < 3.0, f"{name} at {t} us"
            assert 0 < e["eph"] < 5 and 0 < e["epv"] < 5
        gps = data(ulog, "sensor_gps")
        assert min(gps["satellites_used"]) > 0 and max(gps["fix_type"]) == 3
        # Flew about 60 m north-east and came back down.
        last = truth[common[-1]]
        assert math.hypot(last["x"], last["y"]) > 40 and abs(last["z"]) < 1.0


def test_battery_drains_and_modes_follow_the_mission(logs, trajectory):
    for name, ulog in logs.items():
        bat = data(ulog, "battery_status")
        remaining = list(bat["remaining"])
        assert all(b <= a for a, b in zip(remaining, remaining[1:]))
        assert remaining[-1] < remaining[0] <= 1.0
        assert all(0.0 <= r <= 1.0 for r in remaining)
        assert all(v > 10 for v in bat["voltage_v"])
        assert bat["discharged_mah"][-1] > bat["discharged_mah"][0]
        for t, s in by_time(ulog, "battery_status").items():
            row = trajectory[name].get(t)
            if row:
                assert s["remaining"] == pytest.approx(float(row["battery_remaining"]), abs=1e-4)

        status = data(ulog, "vehicle_status")
        modes = [int(m) for m in status["nav_state"]]
        # Disarmed in loiter until the height estimate has settled (a few seconds), then
        # takeoff as the mission's first item (AUTO_MISSION in PX4 too), AUTO_LAND, and
        # loiter (idle) on the ground.
        transitions = [m for i, m in enumerate(modes) if i == 0 or m != modes[i - 1]]
        assert transitions == [NAV_LOITER, NAV_MISSION, NAV_LAND, NAV_LOITER], transitions
        arming = [int(a) for a in status["arming_state"]]
        arming_changes = [a for i, a in enumerate(arming) if i == 0 or a != arming[i - 1]]
        assert arming_changes == [DISARMED, ARMED, DISARMED], arming_changes

        out = data(ulog, "actuator_outputs")
        assert set(out["noutputs"]) == {4}
        flying = [i for i, t in enumerate(out["timestamp"]) if 5e6 < t < 10e6]
        assert all(1000 < out["output[0]"][i] <= 2000 for i in flying)
        assert all(out["output[4]"][i] == 0 for i in flying)

        messages = [(m.log_level_str(), m.message) for m in ulog.logged_messages]
        assert ("INFO", "[commander] Armed") in messages, messages
        assert ("INFO", "[commander] mode: Mission -> Land") in messages, messages
        assert ("INFO", "[navigator] mission item 1 reached") in messages, messages
        assert ("INFO", "[sadesim] run ended: duration") in messages, messages


def test_pyulog_command_line_tools_read_the_files(run, venv_bin):
    for path in sorted((run / "ulog").glob("*.ulg")):
        info = subprocess.run([str(venv_bin / "ulog_info"), str(path)], capture_output=True, text=True)
        assert info.returncode == 0, info.stderr
        assert "vehicle_local_position" in info.stdout and "sys_name: SADE-SIM" in info.stdout
        params = subprocess.run([str(venv_bin / "ulog_params"), str(path)], capture_output=True, text=True)
        assert params.returncode == 0, params.stderr
        assert "SYS_AUTOSTART,4001" in params.stdout.splitlines()
        messages = subprocess.run([str(venv_bin / "ulog_messages"), str(path)], capture_output=True, text=True)
        assert messages.returncode == 0, messages.stderr
        assert "mode: Mission -> Land" in messages.stdout
