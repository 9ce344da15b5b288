#!/usr/bin/env python3
"""A SADE-SIM vision pilot: precision landing on an ArUco pad with the drone's downward
camera, when GNSS alone would land metres off (the scenario biases every fix).

Run it through its scenario (it is started when the drone is ready):

    sadesim run examples/precision-landing.yaml

What it does, printing each step (pilot.log in the run's output folder):
1. arms, takes off to 10 m (MAV_CMD_NAV_TAKEOFF) and switches to offboard, streaming
   SET_POSITION_TARGET_LOCAL_NED at 20 Hz from a background thread;
2. flies to the pad's latitude and longitude (`--pad`) by GNSS: the pad's local NED
   position is the drone's estimated local position plus the pad's offset from the
   drone's estimated latitude and longitude, so a biased fix shifts it by the bias;
3. looks down: in frames taken after the drone came to rest (`next.jpg?after=T`, the
   camera's base URL from fleet.json), cv2.aruco finds the marker (DICT_4X4_50,
   `--pad-id`), cv2.solvePnP gives its centre in the camera frame from its size
   (`--pad-size-m`) and the pinhole intrinsics of the image size and `--hfov-deg`; the
   offset is turned into body FRD (the camera looks down, the top of the image toward the
   nose: image x right = body right, image y down = body backward, optical axis = body
   down) and rotated to NED by the attitude (ATTITUDE) at the frame's time. The setpoint
   moves by that offset, until the pad is within 8 cm of straight below: the correction
   is relative, so neither the GNSS bias nor where the drone rests around its setpoint
   matters;
4. descends in steps (10, 6, 3.5, 2 m above home), re-centring at each, then lands
   straight down on the last setpoint (offboard, the setpoint below the ground), disarms
   and exits 0.

With `--no-camera` (or PRECISION_LANDING_CAMERA=0 in its environment) it skips step 3:
the same flight by GNSS alone, which lands off the pad by the GNSS bias.

Needs `pip install pymavlink opencv-python-headless numpy`.
"""
import argparse
import json
import math
import os
import sys
import threading
import time
import urllib.error
import urllib.request
from collections import deque

# Must be set before pymavlink is imported: SADE-SIM drones speak MAVLink 2 (as PX4 does).
os.environ["MAVLINK20"] = "1"
import cv2  # noqa: E402
import numpy as np  # noqa: E402
from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink

# Heights above home of the descent, m: the drone re-centres over the pad at each.
STEPS_M = [10.0, 6.0, 3.5, 2.0]
# Settled: over the last SETTLE_WINDOW_S (simulated), the estimated position moved slower
# than SETTLED_MPS and its mean is within SETTLED_M of the setpoint on each axis.
SETTLE_WINDOW_S = 1.0
# ... and at least SETTLE_MIN_S (simulated) after the setpoint changed.
SETTLE_MIN_S = 2.5
SETTLED_M = 1.0
SETTLED_MPS = 0.1
# Re-centre until the pad is within this of straight below, m (at most MAX_CORRECTIONS
# times per height).
CENTRED_M = 0.08
MAX_CORRECTIONS = 4
# The last descent: the setpoint this far below the ground, m, until the drone is down.
BELOW_GROUND_M = 2.0
# Frames per measurement (the median of their offsets is used).
FRAMES_PER_LOOK = 5
# Wall-clock limits (the scenario's clock may run faster than real time).
READY_TIMEOUT_S = 60
MOVE_TIMEOUT_S = 60
LAND_TIMEOUT_S = 90
# PX4's custom main mode OFFBOARD (MAV_CMD_DO_SET_MODE param 2).
PX4_MAIN_MODE_OFFBOARD = 6
# SET_POSITION_TARGET_*: position only (velocity, acceleration, yaw and yaw rate ignored).
POSITION_ONLY = 0b1101_1111_1000
EARTH_RADIUS_M = 6378137.0


class PilotError(Exception):
    pass


def log(text):
    print(text, flush=True)


def url_for_pymavlink(url):
    """Fleet-file URLs use MAVSDK's syntax (`udpout://127.0.0.1:24600`); pymavlink wants
    `udpout:127.0.0.1:24600`."""
    scheme, _, address = url.partition("://")
    return {"tcpout": "tcp"}.get(scheme, scheme) + ":" + address


def offset_ne_m(from_lat, from_lon, to_lat, to_lon):
    """North and east metres from one point to another nearby (local tangent plane)."""
    north = math.radians(to_lat - from_lat) * EARTH_RADIUS_M
    east = math.radians(to_lon - from_lon) * EARTH_RADIUS_M * math.cos(math.radians(from_lat))
    return north, east


def body_to_ned(roll, pitch, yaw):
    """Rotation matrix body FRD -> NED for MAVLink's ATTITUDE angles (rad, ZYX order)."""
    cr, sr, cp, sp, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    return np.array([
        [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
        [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
        [-sp, sr * cp, cr * cp],
    ])


class PadFinder:
    """The pad in a downward camera image: its centre relative to the camera, in body FRD."""

    def __init__(self, pad_id, size_m, hfov_deg):
        self.pad_id = pad_id
        self.hfov_deg = hfov_deg
        half = size_m / 2.0
        # ArUco corner order: top-left, top-right, bottom-right, bottom-left (marker x
        # right, y up, centre at the origin).
        self.corners_m = np.array([[-half, half, 0], [half, half, 0], [half, -half, 0], [-half, -half, 0]], np.float64)
        dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
        parameters = cv2.aruco.DetectorParameters()
        parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX  # sub-pixel corners
        self.detector = cv2.aruco.ArucoDetector(dictionary, parameters)

    def intrinsics(self, width_px, height_px):
        """Pinhole camera matrix: square pixels, centred principal point, no distortion."""
        f = (width_px / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)
        return np.array([[f, 0, (width_px - 1) / 2.0], [0, f, (height_px - 1) / 2.0], [0, 0, 1]], np.float64)

    def find(self, image):
        """The pad's centre in body FRD, metres from the camera, or None when not seen."""
        corners, ids, _ = self.detector.detectMarkers(image)
        if ids is None:
            return None
        for c, marker_id in zip(corners, ids.ravel()):
            if marker_id != self.pad_id:
                continue
            height_px, width_px = image.shape[:2]
            ok, _, tvec = cv2.solvePnP(self.corners_m, c.reshape(4, 2).astype(np.float64),
                                       self.intrinsics(width_px, height_px), None, flags=cv2.SOLVEPNP_IPPE_SQUARE)
            if not ok:
                return None
            x_right, y_down, z_optical = tvec.ravel()
            # Camera looking down, top of the image toward the nose.
            return np.array([-y_down, x_right, z_optical])
        return None


class Drone:
    """The drone's MAVLink connection: a background thread sends the ground station's
    heartbeat and streams the current setpoint; the main thread reads telemetry."""

    def __init__(self, info):
        self.name = info["name"]
        self.sysid = info["systemId"]
        self.compid = info["componentId"]
        self.link = mavutil.mavlink_connection(
            url_for_pymavlink(info["mavlink"]["udp"]), source_system=255, source_component=190
        )
        self.send_lock = threading.Lock()
        self.setpoint_ned = None  # (north, east, down) m, streamed while set
        self.setpoint_since = 0.0  # sim s the setpoint was last moved by `go`
        self.stop = threading.Event()
        # Telemetry, newest last: (sim s, ...).
        self.positions = deque(maxlen=200)  # (t, north, east, down, vn, ve, vd)
        self.attitudes = deque(maxlen=200)  # (t, roll, pitch, yaw)
        self.global_position = None  # (t, lat, lon, alt_msl_m, relative_alt_m)
        self.armed = False
        self.landed_state = None
        self.streamer = threading.Thread(target=self._stream, daemon=True)
        self.streamer.start()

    def send(self, fn, *args):
        with self.send_lock:
            fn(*args)

    def _stream(self):
        next_heartbeat = 0.0
        while not self.stop.is_set():
            now = time.monotonic()
            if now >= next_heartbeat:
                self.send(self.link.mav.heartbeat_send, mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                next_heartbeat = now + 1.0
            sp = self.setpoint_ned
            if sp is not None:
                self.send(self.link.mav.set_position_target_local_ned_send, 0, self.sysid, 1,
                          mavlink.MAV_FRAME_LOCAL_NED, POSITION_ONLY, sp[0], sp[1], sp[2], 0, 0, 0, 0, 0, 0, 0, 0)
            time.sleep(0.05)

    def close(self):
        self.stop.set()
        self.streamer.join(timeout=2)
        self.link.close()

    def pump(self, timeout_s):
        """Reads telemetry for up to `timeout_s`; returns the last message read."""
        msg = self.link.recv_match(blocking=True, timeout=timeout_s)
        while msg is not None:
            self._note(msg)
            last = msg
            msg = self.link.recv_match(blocking=False)
            if msg is None:
                return last
        return None

    def _note(self, msg):
        if msg.get_srcSystem() != self.sysid:
            return
        kind = msg.get_type()
        if kind == "LOCAL_POSITION_NED":
            self.positions.append((msg.time_boot_ms / 1000.0, msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz))
        elif kind == "ATTITUDE":
            self.attitudes.append((msg.time_boot_ms / 1000.0, msg.roll, msg.pitch, msg.yaw))
        elif kind == "GLOBAL_POSITION_INT":
            self.global_position = (msg.time_boot_ms / 1000.0, msg.lat * 1e-7, msg.lon * 1e-7, msg.alt / 1000.0,
                                    msg.relative_alt / 1000.0)
        elif kind == "HEARTBEAT" and msg.get_srcComponent() == self.compid:
            self.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        elif kind == "EXTENDED_SYS_STATE":
            self.landed_state = msg.landed_state
        elif kind == "STATUSTEXT":
            log(f"drone says: {msg.text}")

    def wait_for(self, what, condition, timeout_s):
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                raise PilotError(f"timed out waiting for {what}")
            self.pump(0.1)

    def command(self, command, *params):
        """COMMAND_LONG; returns the COMMAND_ACK result."""
        p = list(params) + [0] * (7 - len(params))
        self.send(self.link.mav.command_long_send, self.sysid, 1, command, 0, *p)
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            msg = self.link.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.2)
            if msg is not None and msg.get_srcSystem() == self.sysid and msg.command == command:
                return msg.result
        raise PilotError(f"no COMMAND_ACK for command {command}")

    def slow_streams(self):
        """Telemetry this pilot reads, at rates Python keeps up with (20 Hz)."""
        for message_id in (mavlink.MAVLINK_MSG_ID_ATTITUDE, mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
                           mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT):
            self.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, message_id, 50_000)

    # Telemetry at a simulated instant.

    def position_at(self, t):
        return min(self.positions, key=lambda p: abs(p[0] - t))

    def attitude_at(self, t):
        return min(self.attitudes, key=lambda a: abs(a[0] - t))

    def settled(self):
        """Still, near the setpoint. Judged from the estimated position's movement over the
        last second, not from the estimated velocity or the distance to the setpoint: the
        estimate wanders and its velocity carries the accelerometer's bias, so the drone can
        come to rest a few decimetres from its setpoint in the estimate's frame."""
        if not self.positions or self.setpoint_ned is None:
            return False
        now = self.positions[-1][0]
        if now - self.setpoint_since < SETTLE_MIN_S:
            return False  # give the controller time to react before judging its rest
        recent = np.array([p[1:4] for p in self.positions if p[0] > now - SETTLE_WINDOW_S])
        if len(recent) < 6:
            return False
        half = len(recent) // 2
        drift_mps = np.linalg.norm(recent[half:].mean(axis=0) - recent[:half].mean(axis=0)) / (SETTLE_WINDOW_S / 2)
        off_m = np.abs(recent.mean(axis=0) - np.array(self.setpoint_ned))
        return drift_mps < SETTLED_MPS and off_m.max() < SETTLED_M

    def go(self, north, east, down, what):
        self.setpoint_ned = (north, east, down)
        self.setpoint_since = self.positions[-1][0]
        log(f"{what}: setpoint N {north:.2f} E {east:.2f} D {down:.2f} (local NED, m)")
        try:
            self.wait_for(what, self.settled, MOVE_TIMEOUT_S)
        except PilotError as e:
            t, n, e_, d, vn, ve, vd = self.positions[-1]
            raise PilotError(f"{e}: at {t:.1f} s the estimate is N {n:.2f} E {e_:.2f} D {d:.2f}, "
                             f"moving {vn:+.2f} {ve:+.2f} {vd:+.2f} m/s") from None


class Pilot:
    def __init__(self, args, info):
        self.args = args
        self.drone = Drone(info)
        self.home = info["home"]
        cameras = info.get("cameras", {})
        self.camera_url = cameras.get(args.camera) if args.camera_on else None
        if args.camera_on and self.camera_url is None:
            raise PilotError(f"drone {info['name']} has no camera {args.camera!r} in fleet.json "
                             f"(cameras: {sorted(cameras)}): does the run render cameras (spec.rendering.enabled)?")
        self.finder = PadFinder(args.pad_id, args.pad_size_m, args.hfov_deg)
        self.home_down_m = None  # local NED down of home (the ground)

    def fly(self):
        d = self.drone
        d.slow_streams()
        d.wait_for("a 3D GNSS fix and a position estimate",
                   lambda: d.global_position is not None and d.positions and d.attitudes, READY_TIMEOUT_S)
        deadline = time.monotonic() + READY_TIMEOUT_S
        while (result := d.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)) != mavlink.MAV_RESULT_ACCEPTED:
            if time.monotonic() > deadline:
                raise PilotError(f"arming refused (MAV_RESULT {result})")
            time.sleep(1)
        log("armed")
        _, _, _, alt_msl_m, rel_m = d.global_position
        self.home_down_m = d.positions[-1][3] + rel_m
        cruise_m = STEPS_M[0]
        result = d.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, 0, 0, alt_msl_m - rel_m + cruise_m)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise PilotError(f"takeoff refused (MAV_RESULT {result})")
        log(f"taking off to {cruise_m:.0f} m")
        d.wait_for("the takeoff altitude", lambda: d.global_position[4] > cruise_m - 0.3, MOVE_TIMEOUT_S)

        # Offboard: stream a setpoint where the drone is, then switch.
        _, n, e, *_ = d.positions[-1]
        d.setpoint_ned = (n, e, self.down_at(cruise_m))
        time.sleep(0.3)
        result = d.command(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                           PX4_MAIN_MODE_OFFBOARD, 0)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise PilotError(f"offboard refused (MAV_RESULT {result})")
        log("offboard")

        # To the pad by GNSS: its offset from the estimated latitude and longitude.
        d.pump(0.2)
        t, lat, lon, _, _ = d.global_position
        _, n, e, *_ = d.position_at(t)
        dn, de = offset_ne_m(lat, lon, self.args.pad_lat, self.args.pad_lon)
        target_n, target_e = n + dn, e + de
        log(f"the pad is {math.hypot(dn, de):.1f} m away by GNSS")
        d.go(target_n, target_e, self.down_at(cruise_m), "over the pad by GNSS")

        for k, height_m in enumerate(STEPS_M):
            if k > 0:
                d.go(target_n, target_e, self.down_at(height_m), f"down to {height_m:.1f} m")
            for _ in range(MAX_CORRECTIONS if self.camera_url else 0):
                seen = self.look()
                if seen is None:
                    log(f"at {height_m:.1f} m: pad {self.args.pad_id} not seen; keeping the setpoint")
                    break
                off_n, off_e, below_m = seen
                log(f"at {height_m:.1f} m: pad {self.args.pad_id} seen {below_m:.2f} m below, "
                    f"{math.hypot(off_n, off_e):.2f} m off (N {off_n:+.2f} E {off_e:+.2f})")
                if math.hypot(off_n, off_e) < CENTRED_M:
                    break
                # Move the setpoint by the offset seen: whatever separates the drone from its
                # setpoint at rest (the estimate's bias, the GNSS bias) stays the same.
                target_n, target_e = target_n + off_n, target_e + off_e
                d.go(target_n, target_e, self.down_at(height_m), f"re-centred at {height_m:.1f} m")

        self.land(target_n, target_e)

    def down_at(self, height_m):
        """Local NED down of `height_m` above home."""
        return self.home_down_m - height_m

    def look(self):
        """Where the pad is from the drone: north and east (m, local NED) and its depth below
        the camera, the median over FRAMES_PER_LOOK frames taken after now; None when never
        seen."""
        d = self.drone
        after = d.attitudes[-1][0]
        found = []
        for _ in range(FRAMES_PER_LOOK):
            try:
                with urllib.request.urlopen(f"{self.camera_url}next.jpg?after={after:.3f}", timeout=30) as r:
                    body, t = r.read(), float(r.headers["X-Sim-Time"])
            except (urllib.error.URLError, OSError) as e:
                log(f"camera: {e}")
                return None
            after = t
            # Telemetry up to the frame's time, to find the attitude it was taken with.
            deadline = time.monotonic() + 2
            while d.attitudes[-1][0] < t and time.monotonic() < deadline:
                d.pump(0.05)
            image = cv2.imdecode(np.frombuffer(body, np.uint8), cv2.IMREAD_COLOR)
            frd = self.finder.find(image)
            if frd is None:
                continue
            _, roll, pitch, yaw = d.attitude_at(t)
            found.append(body_to_ned(roll, pitch, yaw) @ frd)
        if not found:
            return None
        return tuple(float(v) for v in np.median(np.array(found), axis=0))

    def land(self, north, east):
        """Straight down on the setpoint that centred the pad (offboard: MAV_CMD_NAV_LAND
        would hold the estimated position instead, which is not where the drone came to
        rest), then disarm on the ground."""
        d = self.drone
        d.setpoint_ned = (north, east, self.home_down_m + BELOW_GROUND_M)
        log("landing")
        d.wait_for("touchdown", lambda: d.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND, LAND_TIMEOUT_S)
        deadline = time.monotonic() + 10
        while d.armed:
            if d.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0) != mavlink.MAV_RESULT_ACCEPTED:
                if time.monotonic() > deadline:
                    raise PilotError("disarming refused on the ground")
                time.sleep(0.5)
            d.pump(0.5)
        d.setpoint_ned = None
        _, lat, lon, _, _ = d.global_position
        dn, de = offset_ne_m(self.args.pad_lat, self.args.pad_lon, lat, lon)
        log(f"landed and disarmed, {math.hypot(dn, de):.2f} m from the pad by GNSS "
            f"(N {dn:+.2f} E {de:+.2f}; the GNSS bias is in this figure)")


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--pad", required=True, metavar="LAT,LON", help="the landing pad's centre, degrees")
    p.add_argument("--pad-id", type=int, default=23, help="the pad's ArUco id (DICT_4X4_50)")
    p.add_argument("--pad-size-m", type=float, default=1.5, help="the marker's edge, metres")
    p.add_argument("--camera", default="down", help="the downward camera's name (spec.fleet[].cameras)")
    p.add_argument("--hfov-deg", type=float, default=90.0, help="the camera's horizontalFovDeg")
    p.add_argument("--no-camera", action="store_true",
                   help="land by GNSS alone (also PRECISION_LANDING_CAMERA=0)")
    args = p.parse_args(argv)
    args.pad_lat, args.pad_lon = (float(v) for v in args.pad.split(","))
    args.camera_on = not args.no_camera and os.environ.get("PRECISION_LANDING_CAMERA", "1") != "0"
    return args


def main():
    args = parse_args(sys.argv[1:])
    fleet_path = os.environ.get("SADESIM_FLEET")
    if not fleet_path:
        sys.exit("SADESIM_FLEET is not set: run this pilot through `sadesim run`, or point it at a run's fleet.json")
    with open(fleet_path, encoding="utf-8") as f:
        fleet = json.load(f)
    info = next(d for d in fleet["drones"] if not d["scripted"])
    log(f"run {fleet['run']}: drone {info['name']} lands on ArUco pad {args.pad_id} at {args.pad_lat}, {args.pad_lon} "
        f"{'with its camera' if args.camera_on else 'by GNSS alone (no camera)'}")
    pilot = None
    try:
        pilot = Pilot(args, info)
        pilot.fly()
    except PilotError as e:
        print(f"FAILED: {e}", file=sys.stderr, flush=True)
        sys.exit(1)
    finally:
        if pilot is not None:
            pilot.drone.close()


if __name__ == "__main__":
    main()
