"""Onboard cameras in a run, checked with OpenCV as a vision pilot would use them: a drone
hovering over an ArUco landing pad sees the pad's id in its downward camera's PNG, the
depth PNG measures its height, `next.jpg?after=t` hands over the next frame at the
camera's rate, and `cv2.VideoCapture` opens the MJPEG stream. After the run, the frames
recorded in `recording.mcap` are read with Foxglove's `mcap` reader and Pillow, and the
recorded `CameraCalibration` and poses put the pad's corners where OpenCV finds them.

Frames are rendered through wgpu on Vulkan: Mesa's lavapipe (tests/install-tools.sh).
"""
import io
import json
import math
import os
import pathlib
import signal
import subprocess
import time
import types
import urllib.request

import cv2
import numpy as np
import pytest
import yaml
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from PIL import Image

from test_recording_mcap import file_descriptors, official
from test_view import read_line_matching

REPO = pathlib.Path(__file__).resolve().parents[2]
PAD = {"latitudeDeg": 41.8826, "longitudeDeg": -87.6225}
HOVER_AGL_M = 8.0
PAD_ID = 7
PAD_SIZE_M = 1.5
PAD_YAW_DEG = 20.0
RECORD_HZ = 2

pytestmark = pytest.mark.skipif(
    not any(pathlib.Path("/usr/share/vulkan/icd.d").glob("lvp_icd*.json")),
    reason="needs Mesa's lavapipe (mesa-vulkan-drivers, tests/install-tools.sh)",
)


@pytest.fixture(scope="module")
def hover(sadesim, tmp_path_factory):
    """One drone from the pad up to 8 m, hovering, with a downward camera at 10 Hz (2 Hz
    into the recording); `base` is the camera's URL, `proc` the run, `runs` its folder."""
    tmp = tmp_path_factory.mktemp("cameras")
    doc = yaml.safe_load((REPO / "examples" / "quickstart.yaml").read_text())
    spec = doc["spec"]
    spec["duration"] = "60s"
    spec["clock"] = {"mode": "scaled", "factor": 2}
    spec["rendering"] = {"enabled": True}
    spec["zones"] = []
    spec["world"]["markers"] = [{"name": "pad", "position": PAD, "sizeM": PAD_SIZE_M, "yawDeg": PAD_YAW_DEG,
                                     "arucoId": PAD_ID}]
    group = spec["fleet"][0]
    group["count"] = 1
    group["homes"] = {"explicit": [PAD]}
    group["mission"] = {"speedMps": 4, "items": [{"takeoff": {"altitudeAglM": HOVER_AGL_M}}, {"loiter": {"holdS": 120}}]}
    group["cameras"] = [{"name": "down", "widthPx": 320, "heightPx": 240, "horizontalFovDeg": 90, "rateHz": 10,
                         "recordRateHz": RECORD_HZ, "mount": {"pitchDeg": 90}, "depth": True}]
    scenario = tmp / "hover.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    proc = subprocess.Popen([sadesim, "run", str(scenario), "--out", str(tmp / "runs"), "--no-mavlink"], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, cwd=tmp,
                            env={**os.environ, "SADESIM_CACHE_DIR": str(tmp / "cache")})
    try:
        url = read_line_matching(proc, r"onboard cameras: (http://\S+)", 300).group(1)
        yield types.SimpleNamespace(base=f"{url}/scouts-0/down/", proc=proc, runs=tmp / "runs")
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=120)


def fetch(url):
    with urllib.request.urlopen(url, timeout=60) as r:
        return r.read(), float(r.headers["X-Sim-Time"])


def hovering_frame(base, fmt="latest.png"):
    """The first frame taken once the drone hovers (takeoff done: 10 s in)."""
    deadline = time.monotonic() + 120
    while True:
        try:
            body, t = fetch(base + fmt)
            if t >= 12.0:
                return body, t
        except urllib.error.HTTPError as e:
            if e.code != 503:  # no frame yet
                raise
        assert time.monotonic() < deadline, "no frame after 12 s of simulated time"
        time.sleep(0.5)


def test_the_downward_camera_sees_the_pads_aruco_id(hover):
    png, t = hovering_frame(hover.base)
    image = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert image.shape == (240, 320, 3)
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50))
    corners, ids, _ = detector.detectMarkers(image)
    assert ids is not None and ids.ravel().tolist() == [PAD_ID], f"at {t} s: {ids}"
    # Straight below the drone: the pad's centre is near the image centre.
    centre = corners[0][0].mean(axis=0)
    assert np.hypot(centre[0] - 159.5, centre[1] - 119.5) < 40, centre


def test_the_depth_image_measures_the_height(hover):
    png, t = hovering_frame(hover.base, "depth.png")
    depth = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and depth.shape == (240, 320)
    centre_m = depth[118:122, 158:162].mean() / 1000.0
    assert abs(centre_m - HOVER_AGL_M) < 1.0, f"{centre_m} m below the drone at {t} s"


def test_next_hands_over_the_following_frame(hover):
    _, t = hovering_frame(hover.base, "latest.jpg")
    body, t_next = fetch(hover.base + f"next.jpg?after={t}")
    assert body[:2] == b"\xff\xd8"
    assert abs((t_next - t) - 0.1) < 1e-6, (t, t_next)


def test_opencv_opens_the_mjpeg_stream(hover):
    capture = cv2.VideoCapture(hover.base + "stream.mjpg")
    try:
        assert capture.isOpened()
        ok, frame = capture.read()
        assert ok and frame.shape == (240, 320, 3)
    finally:
        capture.release()


def finished_recording(hover):
    """The run's `recording.mcap` once the run has ended (its 60 simulated seconds)."""
    hover.proc.wait(timeout=300)
    assert hover.proc.returncode == 0, hover.proc.stdout.read()
    (mcap,) = hover.runs.glob("*/*/recording.mcap")
    return mcap


def quaternion_matrix(q):
    """Rotation matrix of a Foxglove quaternion (x, y, z, w)."""
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def stamp_ns(t):
    return t.seconds * 1_000_000_000 + t.nanos


def test_the_recording_holds_the_frames_with_foxglove_schemas(hover):
    mcap = finished_recording(hover)
    with open(mcap, "rb") as f:
        summary = make_reader(f).get_summary()
    by_name = {s.name: s for s in summary.schemas.values()}
    for name, cls in [("foxglove.CompressedImage", CompressedImage), ("foxglove.CameraCalibration", CameraCalibration),
                      ("foxglove.RawImage", RawImage)]:
        ours, theirs = file_descriptors(by_name[name].data), official(cls)
        file_name = cls.DESCRIPTOR.file.name
        assert ours[file_name] == theirs[file_name], name
    topics = {c.topic: c for c in summary.channels.values()}
    stats = summary.statistics.channel_message_counts
    image_topic = "/drones/scouts-0/cameras/down/image"
    # 60 simulated seconds at 2 Hz, the first frame at the first window.
    assert abs(stats[topics[image_topic].id] - 60 * RECORD_HZ) <= 1, stats[topics[image_topic].id]
    assert stats[topics["/drones/scouts-0/cameras/down/depth"].id] == stats[topics[image_topic].id]

    with open(mcap, "rb") as f:
        reader = make_reader(f, decoder_factories=[ProtobufDecoderFactory()])
        frames = {}
        for schema, channel, message, decoded in reader.iter_decoded_messages(topics=[image_topic, "/drones/scouts-0/cameras/down/depth"]):
            frames.setdefault(message.log_time, {})[schema.name] = decoded
    at_12s = min(t for t in frames if t >= 12_000_000_000)
    image = frames[at_12s]["foxglove.CompressedImage"]
    assert (image.format, image.frame_id) == ("jpeg", "drone/scouts-0/down")
    picture = Image.open(io.BytesIO(image.data))
    assert (picture.format, picture.size, picture.mode) == ("JPEG", (320, 240), "RGB")
    depth = frames[at_12s]["foxglove.RawImage"]
    assert (depth.encoding, depth.width, depth.height, depth.step) == ("16UC1", 320, 240, 640)
    mm = np.frombuffer(depth.data, "<u2").reshape(240, 320)
    assert abs(mm[118:122, 158:162].mean() / 1000.0 - HOVER_AGL_M) < 1.0


def test_the_recorded_calibration_projects_the_pad_where_opencv_finds_it(hover):
    """The pad's centre and corners (known 3-D points), projected with the recorded K, the
    recorded drone pose and the camera's recorded mount, land within 1 px of the corners
    OpenCV detects in the recorded image."""
    mcap = finished_recording(hover)
    camera = "/drones/scouts-0/cameras/down/"
    with open(mcap, "rb") as f:
        reader = make_reader(f, decoder_factories=[ProtobufDecoderFactory()])
        by_topic = {}
        for _, channel, message, decoded in reader.iter_decoded_messages(
                topics=[camera + "image", camera + "calibration", "/drones/scouts-0/pose", "/tf"]):
            by_topic.setdefault(channel.topic, []).append((message.log_time, decoded))
    mount = next(t for _, m in by_topic["/tf"] for t in m.transforms if t.child_frame_id == "drone/scouts-0/down")
    assert mount.parent_frame_id == "drone/scouts-0"
    poses = {stamp_ns(p.timestamp): p.pose for _, p in by_topic["/drones/scouts-0/pose"]}
    # The pad as the recording's `/markers` scene places it: centre on the ground, yaw.
    with open(mcap, "rb") as f:
        (_, _, message), = make_reader(f).iter_messages(topics=["/markers"])
    (entity,) = json.loads(message.data)["entities"]
    assert entity["id"] == "marker/pad"
    assert {m["key"]: m["value"] for m in entity["metadata"]}["arucoId"] == str(PAD_ID)
    cube = entity["cubes"][0]
    pad = np.array([cube["pose"]["position"][k] for k in "xyz"])
    assert cube["size"]["x"] == PAD_SIZE_M
    assert abs(2 * math.degrees(math.atan2(cube["pose"]["orientation"]["z"], cube["pose"]["orientation"]["w"])) - PAD_YAW_DEG) < 1e-9
    yaw = math.radians(PAD_YAW_DEG)
    half = PAD_SIZE_M / 2
    rotate = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    corners_enu = [pad + np.append(rotate @ np.array(c), 0.0) for c in [(-half, half), (half, half), (half, -half), (-half, -half)]]
    checked = 0
    calibrations = dict(by_topic[camera + "calibration"])
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50))
    parameters = cv2.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector.setDetectorParameters(parameters)
    for log_time, image in by_topic[camera + "image"]:
        if log_time < 12_000_000_000:
            continue
        calibration = calibrations[log_time]
        assert calibration.frame_id == image.frame_id and list(calibration.D) == []
        k = np.array(calibration.K).reshape(3, 3)
        pose = poses[stamp_ns(image.timestamp)]
        body_to_world = quaternion_matrix(pose.orientation)
        body = np.array([pose.position.x, pose.position.y, pose.position.z])
        optical_to_body = quaternion_matrix(mount.rotation)
        offset = np.array([mount.translation.x, mount.translation.y, mount.translation.z])

        def project(point_enu):
            in_body = body_to_world.T @ (point_enu - body)
            x, y, z = optical_to_body.T @ (in_body - offset)
            u, v, w = k @ np.array([x, y, z])
            return np.array([u / w, v / w])

        gray = np.asarray(Image.open(io.BytesIO(image.data)).convert("L"))
        corners, ids, _ = detector.detectMarkers(gray)
        assert ids is not None and ids.ravel().tolist() == [PAD_ID], f"at {log_time} ns"
        found = corners[0][0]
        expected = np.array([project(c) for c in corners_enu])
        centre_error = np.linalg.norm(found.mean(axis=0) - project(pad))
        assert centre_error < 1.0, f"pad centre {centre_error:.2f} px off at {log_time} ns"
        # Each detected corner (OpenCV's order) next to its projection; a single corner of a
        # 30-pixel marker in a JPEG is found to about a pixel (2 px where the sub-pixel
        # refinement gives up and returns a whole pixel), their mean much better.
        errors = np.linalg.norm(found - expected, axis=1)
        assert errors.mean() < 1.5 and errors.max() < 2.5, \
            f"corners {errors.round(2)} px off at {log_time} ns: {found} vs {expected}"
        checked += 1
    assert checked >= 50, checked


def test_the_summary_counts_each_cameras_frames(hover):
    finished_recording(hover)
    (summary,) = hover.runs.glob("*/*/summary.json")
    (tally,) = json.loads(summary.read_text())["cameras"]
    assert (tally["drone"], tally["camera"]) == ("scouts-0", "down")
    # 60 simulated seconds at 10 Hz, the first frame at the first window.
    assert abs(tally["frames"] - 600) <= 1, tally
    assert 0 <= tally["late"] <= tally["frames"]


def test_frames_a_machine_cannot_render_in_time_are_counted_late(sadesim, tmp_path):
    """A clock no renderer can keep up with (1000x: a 100 Hz camera is 100 000 frames per
    wall second): the run still renders every frame, counts them late in summary.json, and
    warns."""
    doc = yaml.safe_load((REPO / "examples" / "quickstart.yaml").read_text())
    spec = doc["spec"]
    spec["duration"] = "3s"
    spec["clock"] = {"mode": "scaled", "factor": 1000}
    spec["rendering"] = {"enabled": True}
    group = spec["fleet"][0]
    group["count"] = 1
    group["cameras"] = [{"name": "front", "widthPx": 320, "heightPx": 240, "horizontalFovDeg": 90, "rateHz": 100,
                         "recordRateHz": 0}]
    scenario = tmp_path / "fast.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    done = subprocess.run([sadesim, "run", str(scenario), "--out", str(tmp_path / "runs"), "--no-mavlink"],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path,
                          env={**os.environ, "SADESIM_CACHE_DIR": str(tmp_path / "cache")})
    assert done.returncode == 0, done.stderr
    (summary,) = (tmp_path / "runs").glob("*/*/summary.json")
    (tally,) = json.loads(summary.read_text())["cameras"]
    assert abs(tally["frames"] - 300) <= 1, tally
    assert tally["late"] >= tally["frames"] // 2 and tally["maxLateS"] > 0.0, tally
    assert f"{tally['late']} of {tally['frames']} camera frames were late" in done.stderr, done.stderr
    # Not one frame went missing: recordRateHz 0 keeps them out of the recording only.
    (mcap,) = (tmp_path / "runs").glob("*/*/recording.mcap")
    with open(mcap, "rb") as f:
        topics = {c.topic for c in make_reader(f).get_summary().channels.values()}
    assert not any("/cameras/" in t for t in topics), topics
