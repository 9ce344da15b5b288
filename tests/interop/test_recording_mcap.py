"""`recording.mcap` read with the official `mcap` Python reader: Foxglove schema names,
messages per stream = simulated duration x rate, monotonic times, poses equal to the
ground truth in trajectory.csv, and a run killed with SIGKILL leaves a file that a
streaming reader reads up to its last complete chunk.

The ground-truth streams (pose, /tf, velocity) are protobuf: they are decoded with
`mcap-protobuf-support` from the descriptors in the file, and those descriptors are
compared with Foxglove's own (`foxglove-schemas-protobuf`). The other channels are JSON.

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
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from google.protobuf import descriptor_pb2, timestamp_pb2
from mcap.decoder import DecoderFactory
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory

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
# Schemas encoded as protobuf; every other one is a JSON Schema with JSON messages.
PROTOBUF = {"foxglove.PoseInFrame", "foxglove.FrameTransforms", "sadesim.Velocity"}


class JsonDecoderFactory(DecoderFactory):
    """`json` messages of `jsonschema` channels, as dicts."""

    def decoder_for(self, message_encoding, schema):
        if message_encoding == "json" and schema is not None and schema.encoding == "jsonschema":
            return json.loads
        return None


def to_dict(message) -> dict:
    """A protobuf message as the dict its JSON form would be, with every field (zeros
    included) and `google.protobuf.Timestamp` as Foxglove's JSON time `{sec, nsec}`."""
    if message.DESCRIPTOR.full_name == "google.protobuf.Timestamp":
        return {"sec": message.seconds, "nsec": message.nanos}
    out = {}
    for field in message.DESCRIPTOR.fields:
        value = getattr(message, field.name)
        if field.type == field.TYPE_MESSAGE:
            value = [to_dict(v) for v in value] if field.is_repeated else to_dict(value)
        out[field.name] = value
    return out


def decoded(schema: Schema, channel: Channel, message: Message, factories: dict):
    """The message as a dict, with the decoder its encodings call for."""
    key = (channel.message_encoding, schema.id)
    if key not in factories:
        for factory in (JsonDecoderFactory(), ProtobufDecoderFactory()):
            decoder = factory.decoder_for(channel.message_encoding, schema)
            if decoder is not None:
                factories[key] = decoder
                break
        else:
            raise AssertionError(f"{channel.topic}: no decoder for {channel.message_encoding}/{schema.encoding}")
    value = factories[key](message.data)
    return value if isinstance(value, dict) else to_dict(value)


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
    cache = f"file://{tmp / 'asset-cache'}"
    subprocess.run(
        [sadesim, "run", str(path), "--no-mavlink", "--quiet", "--out", str(out), "--asset-cache", cache],
        check=True, timeout=600,
    )
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
            if s.name in PROTOBUF:
                assert s.encoding == "protobuf", s.name
            else:
                assert s.encoding == "jsonschema", s.name
                assert json.loads(s.data)["title"] == s.name
        factories = {}
        messages = [
            (channel.topic, schema.name, m.log_time, m.publish_time, decoded(schema, channel, m, factories))
            for schema, channel, m in reader.iter_messages(log_time_order=False)
        ]
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            assert channel.message_encoding == ("protobuf" if schema.name in PROTOBUF else "json"), channel.topic
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
    assert by_topic["/world"] == "foxglove.SceneUpdate"
    assert by_topic["/events"] == "foxglove.Log"


def file_descriptors(schema_data: bytes) -> dict:
    return {f.name: f for f in descriptor_pb2.FileDescriptorSet.FromString(schema_data).file}


def official(message_class) -> dict:
    """Foxglove's descriptors of a message's file and everything it imports, by file name."""
    files, todo = {}, [message_class.DESCRIPTOR.file]
    while todo:
        file = todo.pop()
        proto = descriptor_pb2.FileDescriptorProto()
        file.CopyToProto(proto)
        files[file.name] = proto
        todo.extend(file.dependencies)
    return files


def test_protobuf_schemas_are_foxglove_own_descriptors(finished_run):
    folder, _, _ = finished_run
    with open(folder / "recording.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    by_name = {s.name: s for s in summary.schemas.values()}
    for name, message_class in [("foxglove.PoseInFrame", PoseInFrame), ("foxglove.FrameTransforms", FrameTransforms)]:
        ours, theirs = file_descriptors(by_name[name].data), official(message_class)
        assert set(ours) == set(theirs), name
        for file_name, proto in theirs.items():
            if file_name == "google/protobuf/timestamp.proto":
                # Same message; protobuf's copy also carries language options and the
                # optional json_name protoc fills in.
                for field in proto.message_type[0].field:
                    field.ClearField("json_name")
                assert ours[file_name].message_type == proto.message_type
                assert ours[file_name].package == proto.package
            else:
                assert ours[file_name] == proto, file_name
        # Imports come before the files that import them (as a pool adds them).
        order = [f.name for f in descriptor_pb2.FileDescriptorSet.FromString(by_name[name].data).file]
        for i, file_name in enumerate(order):
            assert all(order.index(d) < i for d in ours[file_name].dependency), order
    velocity = file_descriptors(by_name["sadesim.Velocity"].data)["sadesim/Velocity.proto"]
    assert [(f.name, f.number, f.type_name) for f in velocity.message_type[0].field] == [
        ("timestamp", 1, ".google.protobuf.Timestamp"),
        ("frame_id", 2, ""),
        ("velocity_enu_mps", 3, ".foxglove.Vector3"),
        ("rate_body_rps", 4, ".foxglove.Vector3"),
    ]
    assert timestamp_pb2.Timestamp.DESCRIPTOR.full_name == "google.protobuf.Timestamp"


def test_poses_decode_with_foxglove_generated_classes(finished_run):
    folder, _, messages = finished_run
    by_key = {(topic, log_time): msg for topic, _, log_time, _, msg in messages}
    checked = 0
    with open(folder / "recording.mcap", "rb") as f:
        for schema, channel, m in make_reader(f).iter_messages(topics=["/drones/pair-0/pose", "/tf"]):
            cls = PoseInFrame if schema.name == "foxglove.PoseInFrame" else FrameTransforms
            parsed = cls.FromString(m.data)
            assert to_dict(parsed) == by_key[(channel.topic, m.log_time)]
            checked += 1
    assert checked > 1000


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
    assert counts["/world"] == 1
    events = (folder / "events.jsonl").read_text().splitlines()
    assert counts["/events"] == len(events)


def test_timestamps_are_monotonic_and_match_the_messages(finished_run):
    _, _, messages = finished_run
    assert_monotonic(messages)
    for topic, _, _, publish_time, msg in messages:
        if topic == "/tf":
            assert all(stamp_ns(t) == publish_time for t in msg["transforms"])
        elif topic not in ("/zones", "/world"):
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
    # From the ground to 60 m above it (AGL), at every corner: the vertical edges are
    # pairs (floor, ceiling) over the terrain there.
    verticals = entity["lines"][2]["points"]
    assert len(verticals) == 8
    for floor, ceiling in zip(verticals[::2], verticals[1::2]):
        assert (floor["x"], floor["y"]) == (ceiling["x"], ceiling["y"])
        assert abs(ceiling["z"] - floor["z"] - 60.0) <= 0.011, (floor, ceiling)
    logs = [msg for topic, _, _, _, msg in messages if topic == "/events"]
    expected = [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]
    assert [json.loads(m["message"]) for m in logs] == expected
    assert {m["level"] for m in logs} <= {2, 3, 4}


def test_the_city_is_drawn_as_a_scene_of_the_bundle_buildings_and_ground(finished_run):
    """`/world`: the run's buildings and ground as Foxglove triangle lists, consistent with
    the world's footprints in the asset bundle (`buildings.geojson`)."""
    folder, _, messages = finished_run
    (scene,) = [msg for topic, _, log_time, _, msg in messages if topic == "/world" and log_time == 0]
    entities = {e["id"]: e for e in scene["entities"]}
    assert set(entities) == {"buildings", "ground"}
    plan = json.loads((folder / "plan.json").read_text())
    bundle = folder.parent.parent.parent / "asset-cache" / "assets" / plan["assetCacheKey"] / "world"
    geojson = json.loads((bundle / "buildings.geojson").read_text())["features"]
    world = json.loads((folder / "world.json").read_text())
    assert len(geojson) == world["buildingCount"] > 100

    buildings = entities["buildings"]
    assert {"key": "buildings", "value": str(len(geojson))} in buildings["metadata"]
    (solid,) = buildings["triangles"]
    points, indices = solid["points"], solid["indices"]
    assert len(indices) % 3 == 0 and max(indices) < len(points)
    # Two wall triangles per footprint edge (holes included) and the roof and base caps.
    edges = sum(len(ring) - 1 for f in geojson for ring in f["geometry"]["coordinates"])
    walls = 2 * edges
    assert len(indices) // 3 > walls
    origin_msl = plan["spec"]["origin"]["altitudeMslM"]
    roofs = [f["properties"]["baseAltitudeMslM"] + f["properties"]["heightM"] - origin_msl for f in geojson]
    top = max(p["z"] for p in points)
    assert abs(top - max(roofs)) <= 0.02, (top, max(roofs))

    (ground,) = entities["ground"]["triangles"]
    extent = plan["spec"]["world"].get("extentM", 2000)
    xs = [p["x"] for p in ground["points"]]
    assert (min(xs), max(xs)) == (-extent, extent)
    assert len(ground["indices"]) == 3 * 2 * 64 * 64


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
    reader; returns (chunks, messages as (topic, log_time, data), footer seen)."""
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
                    messages.append((channels[r.channel_id], r.log_time, r.data))
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
        # zones) and two of messages (~1 MiB each, compressed to a few hundred kB).
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
            assert stamp_ns(to_dict(PoseInFrame.FromString(msg))) == log_time
    assert len(poses) == 4
    for topic, n in poses.items():
        # No gap: one pose per 10 ms from 10 ms to the last one read.
        assert n == round(last[topic] / 10_000_000), (topic, n, last[topic])
        assert n >= 100
