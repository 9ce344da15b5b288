"""`recording.mcap` read with the official `mcap` Python reader: Foxglove schema names,
messages per stream = simulated duration x rate, monotonic times, poses equal to the
ground truth in trajectory.csv, and a run killed with SIGKILL leaves a file that a
streaming reader reads up to its last complete chunk.

Runs use `--no-mavlink` and scripted missions, so they bind no port and can run beside
other tests.
"""
import collections
import csv
import json
import os
import pathlib
import signal
import subprocess
import time

import pytest
import yaml
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Footer, Message
from mcap.stream_reader import StreamReader, breakup_chunk

ORIGIN = {"latitudeDeg": 41.8796, "longitudeDeg": -87.6237, "altitudeMslM": 181}
PARK = {"latitudeDeg": 41.8818, "longitudeDeg": -87.6226}
HOMES = {"latitudeDeg": 41.8826, "longitudeDeg": -87.6225}

FOXGLOVE = {
    "foxglove.PoseInFrame",
    "foxglove.FrameTransforms",
    "foxglove.LocationFix",
    "foxglove.SceneUpdate",
    "foxglove.Log",
}
PER_DRONE = ["pose", "velocity", "estimate", "motors", "battery", "status", "wind", "location", "gnss"]


def scenario(name: str, duration: str, clock: dict, drones: int = 2, recording: dict | None = None) -> dict:
    """Drones take off, fly to Cloud Gate and land; a zone they never enter."""
    spec = {
        "origin": ORIGIN,
        "duration": duration,
        "clock": clock,
        "seed": 3,
        "environment": {"gnss": {"rateHz": 5}},
        "world": {"openAreas": [{"name": "park", "center": PARK, "radiusM": 250}]},
        "fleet": [
            {
                "name": "pair",
                "count": drones,
                "airframe": "x500",
                "operator": "tests",
                "homes": {"randomInArea": {"center": HOMES, "radiusM": 60}},
                "altitude": {"maxAglM": 60},
                "mission": {
                    "speedMps": 8,
                    "items": [
                        {"takeoff": {"altitudeAglM": 20}},
                        {"waypoint": {"latitudeDeg": 41.8827, "longitudeDeg": -87.6233, "altitudeAglM": 25}},
                        {"land": {}},
                    ],
                },
            }
        ],
        "zones": [
            {
                "name": "museum",
                "polygon": [
                    {"latitudeDeg": 41.8801, "longitudeDeg": -87.6242},
                    {"latitudeDeg": 41.8790, "longitudeDeg": -87.6242},
                    {"latitudeDeg": 41.8790, "longitudeDeg": -87.6228},
                    {"latitudeDeg": 41.8801, "longitudeDeg": -87.6228},
                ],
                "ceiling": {"heightM": 60, "reference": "agl"},
                "policy": {"authorizedOperators": ["someone-else"]},
            }
        ],
    }
    if recording is not None:
        spec["recording"] = recording
    return {"apiVersion": "sadesim.io/v1alpha1", "kind": "SimulationRun", "metadata": {"name": name}, "spec": spec}


def run_to_end(sadesim: str, tmp: pathlib.Path, doc: dict) -> pathlib.Path:
    """`sadesim run --no-mavlink` to the end; returns the run folder."""
    path = tmp / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc))
    out = tmp / "runs"
    subprocess.run([sadesim, "run", str(path), "--no-mavlink", "--quiet", "--out", str(out)], check=True, timeout=600)
    (folder,) = out.glob("*/*/")
    return folder


def read_finished(path: pathlib.Path):
    """Schema names, and (topic, schema, log_time, publish_time, decoded JSON) per message
    in file order."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None, "a finished recording has a summary section"
        schemas = {s.name for s in summary.schemas.values()}
        for s in summary.schemas.values():
            assert s.encoding == "jsonschema", s.name
            assert json.loads(s.data)["title"] == s.name
        messages = [
            (channel.topic, schema.name, m.log_time, m.publish_time, json.loads(m.data))
            for schema, channel, m in reader.iter_messages(log_time_order=False)
        ]
        for channel in summary.channels.values():
            assert channel.message_encoding == "json", channel.topic
    return schemas, messages


def assert_monotonic(messages):
    last = {}
    for topic, _, log_time, publish_time, _ in messages:
        assert log_time >= last.get(topic, 0), f"{topic}: {log_time} after {last[topic]}"
        assert publish_time <= log_time, topic
        last[topic] = log_time


def stamp_ns(msg: dict) -> int:
    return msg["timestamp"]["sec"] * 1_000_000_000 + msg["timestamp"]["nsec"]


@pytest.fixture(scope="module")
def finished_run(sadesim, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("mcap-finished")
    folder = run_to_end(sadesim, tmp, scenario("mcap-finished", "40s", {"mode": "asFastAsPossible"}))
    schemas, messages = read_finished(folder / "recording.mcap")
    return folder, schemas, messages


def test_schemas_are_foxglove_well_known_ones(finished_run):
    _, schemas, messages = finished_run
    assert FOXGLOVE <= schemas, schemas
    by_topic = {topic: schema for topic, schema, *_ in messages}
    assert by_topic["/drones/pair-0/pose"] == "foxglove.PoseInFrame"
    assert by_topic["/tf"] == "foxglove.FrameTransforms"
    assert by_topic["/drones/pair-0/gnss"] == "foxglove.LocationFix"
    assert by_topic["/drones/pair-0/location"] == "foxglove.LocationFix"
    assert by_topic["/zones"] == "foxglove.SceneUpdate"
    assert by_topic["/events"] == "foxglove.Log"


def test_counts_per_stream_are_duration_times_rate(finished_run):
    folder, _, messages = finished_run
    sim_s = json.loads((folder / "summary.json").read_text())["simTimeS"]
    counts = collections.Counter(topic for topic, *_ in messages)
    rates = {"pose": 100, "velocity": 100, "motors": 10, "battery": 10, "status": 10, "wind": 10, "location": 10}
    for drone in ["pair-0", "pair-1"]:
        for stream, hz in rates.items():
            n = counts[f"/drones/{drone}/{stream}"]
            assert abs(n - sim_s * hz) <= 1, f"{drone}/{stream}: {n} for {sim_s} s at {hz} Hz"
        # The estimate starts with the first GNSS fix (within the first seconds).
        n = counts[f"/drones/{drone}/estimate"]
        assert sim_s * 10 - 5 * 10 <= n <= sim_s * 10 + 1, n
        # One message per new fix of the 5 Hz receiver.
        n = counts[f"/drones/{drone}/gnss"]
        assert abs(n - sim_s * 5) <= 1, n
    # One FrameTransforms message per sample, with a transform per drone.
    assert abs(counts["/tf"] - sim_s * 100) <= 1
    for topic, *_, msg in messages:
        if topic == "/tf":
            assert sorted(t["child_frame_id"] for t in msg["transforms"]) == ["drone/pair-0", "drone/pair-1"]
    assert counts["/zones"] == 1
    events = (folder / "events.jsonl").read_text().splitlines()
    assert counts["/events"] == len(events)


def test_timestamps_are_monotonic_and_match_the_messages(finished_run):
    _, _, messages = finished_run
    assert_monotonic(messages)
    for topic, _, _, publish_time, msg in messages:
        if topic == "/tf":
            assert all(stamp_ns(t) == publish_time for t in msg["transforms"])
        elif topic != "/zones":
            assert stamp_ns(msg) == publish_time, topic


def test_poses_equal_the_ground_truth_of_trajectory_csv(finished_run):
    folder, _, messages = finished_run
    poses = {}
    for topic, _, log_time, _, msg in messages:
        if topic.endswith("/pose"):
            assert msg["frame_id"] == "world"
            p = msg["pose"]["position"]
            poses[(topic.split("/")[2], log_time)] = (p["x"], p["y"], p["z"])
    transforms = {
        (t["child_frame_id"].removeprefix("drone/"), log_time): t["translation"]
        for topic, _, log_time, _, msg in messages
        if topic == "/tf"
        for t in msg["transforms"]
    }
    rows = list(csv.DictReader(open(folder / "trajectory.csv")))
    assert len(rows) > 100
    for row in rows:
        key = (row["name"], round(float(row["time_s"]) * 1e9))
        pose = poses[key]
        truth = (float(row["east_m"]), float(row["north_m"]), float(row["up_m"]))
        # Both round to 1 mm (ties may round apart by one step).
        assert all(abs(a - b) <= 1.001e-3 for a, b in zip(pose, truth)), (key, pose, truth)
        t = transforms[key]
        assert (t["x"], t["y"], t["z"]) == pose
    flew = max(float(r["up_m"]) for r in rows) - min(float(r["up_m"]) for r in rows)
    assert flew > 15, "the drones took off"


def test_zones_and_events(finished_run):
    folder, _, messages = finished_run
    (scene,) = [msg for topic, _, _, _, msg in messages if topic == "/zones"]
    (entity,) = scene["entities"]
    assert entity["id"] == "zone/museum" and entity["frame_id"] == "world"
    ups = {round(p["z"], 3) for line in entity["lines"] for p in line["points"]}
    assert ups == {0.0, 60.0}
    logs = [msg for topic, _, _, _, msg in messages if topic == "/events"]
    expected = [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]
    assert [json.loads(m["message"]) for m in logs] == expected
    assert {m["level"] for m in logs} <= {2, 3, 4}


def test_rates_and_compression_come_from_the_spec(sadesim, tmp_path):
    recording = {"compression": "lz4", "ulog": False, "rates": {"groundTruthHz": 20, "statusHz": 2, "actuatorsHz": 1}}
    folder = run_to_end(sadesim, tmp_path, scenario("mcap-rates", "15s", {"mode": "asFastAsPossible"}, 1, recording))
    _, messages = read_finished(folder / "recording.mcap")
    sim_s = json.loads((folder / "summary.json").read_text())["simTimeS"]
    counts = collections.Counter(topic for topic, *_ in messages)
    assert abs(counts["/drones/pair-0/pose"] - sim_s * 20) <= 1
    assert abs(counts["/drones/pair-0/status"] - sim_s * 2) <= 1
    assert abs(counts["/drones/pair-0/motors"] - sim_s * 1) <= 1
    with open(folder / "recording.mcap", "rb") as f:
        chunks = [r for r in StreamReader(f, emit_chunks=True).records if isinstance(r, Chunk)]
    assert chunks and {c.compression for c in chunks} == {"lz4"}
    assert not (folder / "ulog").exists()


def read_truncated(path: pathlib.Path):
    """Messages of every complete chunk of an unfinished file, with the non-seeking
    reader; returns (chunks, messages as (topic, log_time, JSON), footer seen)."""
    channels, chunks, messages, footer = {}, 0, [], False
    with open(path, "rb") as f:
        records = StreamReader(f, emit_chunks=True).records
        while True:
            try:
                record = next(records)
            except (EndOfFile, StopIteration):
                break
            except Exception:  # a record cut by the kill; everything before it counts
                break
            if isinstance(record, Footer):
                footer = True
            if not isinstance(record, Chunk):
                continue
            chunks += 1
            for r in breakup_chunk(record, validate_crc=True):
                if isinstance(r, Channel):
                    channels[r.id] = r.topic
                elif isinstance(r, Message):
                    messages.append((channels[r.channel_id], r.log_time, json.loads(r.data)))
    return chunks, messages, footer


def test_a_killed_run_leaves_a_readable_recording(sadesim, tmp_path):
    # Ten simulated minutes at 10x: still running when we kill it.
    doc = scenario("mcap-killed", "10m", {"mode": "scaled", "factor": 10}, drones=4)
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc))
    out = tmp_path / "runs"
    proc = subprocess.Popen(
        [sadesim, "run", str(path), "--no-mavlink", "--quiet", "--out", str(out)],
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        # Wait until at least three chunks are on disk: the first (schemas, channels,
        # zones) and two of messages (~1 MiB of JSON each, compressed to a few hundred kB).
        deadline = time.monotonic() + 120
        mcap_path = None
        while time.monotonic() < deadline and proc.poll() is None:
            found = list(out.glob("*/*/recording.mcap"))
            if found:
                mcap_path = found[0]
                chunks, _, _ = read_truncated(mcap_path)
                if chunks >= 3:
                    break
            time.sleep(0.2)
        assert proc.poll() is None, f"the run ended early: {proc.stderr.read().decode()}"
        assert mcap_path is not None
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL

    chunks, messages, footer = read_truncated(mcap_path)
    assert not footer, "a killed run has no footer"
    assert chunks >= 3
    last = {}
    poses = collections.Counter()
    for topic, log_time, msg in messages:
        assert log_time >= last.get(topic, 0), topic
        last[topic] = log_time
        if topic.endswith("/pose"):
            poses[topic] += 1
            assert stamp_ns(msg) == log_time
    assert len(poses) == 4
    for topic, n in poses.items():
        # No gap: one pose per 10 ms from 10 ms to the last one read.
        assert n == round(last[topic] / 10_000_000), (topic, n, last[topic])
        assert n >= 100
