"""Onboard cameras in a run, checked with OpenCV as a vision pilot would use them: a drone
hovering over an ArUco landing pad sees the pad's id in its downward camera's PNG, the
depth PNG measures its height, `next.jpg?after=t` hands over the next frame at the
camera's rate, and `cv2.VideoCapture` opens the MJPEG stream.

Frames are rendered through wgpu on Vulkan: Mesa's lavapipe (tests/install-tools.sh).
"""
import os
import pathlib
import signal
import subprocess
import time
import urllib.request

import cv2
import numpy as np
import pytest
import yaml

from test_view import read_line_matching

REPO = pathlib.Path(__file__).resolve().parents[2]
PAD = {"latitudeDeg": 41.8826, "longitudeDeg": -87.6225}
HOVER_AGL_M = 8.0
PAD_ID = 7

pytestmark = pytest.mark.skipif(
    not any(pathlib.Path("/usr/share/vulkan/icd.d").glob("lvp_icd*.json")),
    reason="needs Mesa's lavapipe (mesa-vulkan-drivers, tests/install-tools.sh)",
)


@pytest.fixture(scope="module")
def hover(sadesim, tmp_path_factory):
    """One drone from the pad up to 8 m, hovering, with a downward camera at 10 Hz."""
    tmp = tmp_path_factory.mktemp("cameras")
    doc = yaml.safe_load((REPO / "examples" / "quickstart.yaml").read_text())
    spec = doc["spec"]
    spec["duration"] = "60s"
    spec["clock"] = {"mode": "scaled", "factor": 2}
    spec["rendering"] = {"enabled": True}
    spec["zones"] = []
    spec["world"]["markers"] = [{"name": "pad", "position": PAD, "sizeM": 1.5, "yawDeg": 20, "arucoId": PAD_ID}]
    group = spec["fleet"][0]
    group["count"] = 1
    group["homes"] = {"explicit": [PAD]}
    group["mission"] = {"speedMps": 4, "items": [{"takeoff": {"altitudeAglM": HOVER_AGL_M}}, {"loiter": {"holdS": 120}}]}
    group["cameras"] = [{"name": "down", "widthPx": 320, "heightPx": 240, "horizontalFovDeg": 90, "rateHz": 10,
                         "mount": {"pitchDeg": 90}, "depth": True}]
    scenario = tmp / "hover.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    proc = subprocess.Popen([sadesim, "run", str(scenario), "--out", str(tmp / "runs"), "--no-mavlink"], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, cwd=tmp,
                            env={**os.environ, "SADESIM_CACHE_DIR": str(tmp / "cache")})
    try:
        url = read_line_matching(proc, r"onboard cameras: (http://\S+)", 300).group(1)
        yield f"{url}/scouts-0/down/"
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
    png, t = hovering_frame(hover)
    image = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert image.shape == (240, 320, 3)
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50))
    corners, ids, _ = detector.detectMarkers(image)
    assert ids is not None and ids.ravel().tolist() == [PAD_ID], f"at {t} s: {ids}"
    # Straight below the drone: the pad's centre is near the image centre.
    centre = corners[0][0].mean(axis=0)
    assert np.hypot(centre[0] - 159.5, centre[1] - 119.5) < 40, centre


def test_the_depth_image_measures_the_height(hover):
    png, t = hovering_frame(hover, "depth.png")
    depth = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and depth.shape == (240, 320)
    centre_m = depth[118:122, 158:162].mean() / 1000.0
    assert abs(centre_m - HOVER_AGL_M) < 1.0, f"{centre_m} m below the drone at {t} s"


def test_next_hands_over_the_following_frame(hover):
    _, t = hovering_frame(hover, "latest.jpg")
    body, t_next = fetch(hover + f"next.jpg?after={t}")
    assert body[:2] == b"\xff\xd8"
    assert abs((t_next - t) - 0.1) < 1e-6, (t, t_next)


def test_opencv_opens_the_mjpeg_stream(hover):
    capture = cv2.VideoCapture(hover + "stream.mjpg")
    try:
        assert capture.isOpened()
        ok, frame = capture.read()
        assert ok and frame.shape == (240, 320, 3)
    finally:
        capture.release()
