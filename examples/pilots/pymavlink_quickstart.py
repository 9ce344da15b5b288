#!/usr/bin/env python3
"""A SADE-SIM pilot written with pymavlink: every drone of the fleet flies a short mission
over Millennium Park (take off to 30 m, three waypoints at 40 m, return to launch).

Run it through a scenario (it is started when all drones are ready):

    sadesim run examples/quickstart-pymavlink.yaml

or by hand against a run started with --no-pilot:

    SADESIM_FLEET=runs/quickstart-pymavlink/<time>/fleet.json python3 examples/pilots/pymavlink_quickstart.py

One program flies all drones, one thread per drone, each with its own MAVLink connection
to the drone's endpoint (`mavlink.udp` in the fleet file). The mission is uploaded with the
MAVLink mission protocol and started with MAV_CMD_MISSION_START, as a ground station would
do with PX4. Exits 0 when every drone has landed and disarmed, 1 otherwise.

Needs `pip install pymavlink`.
"""
import json
import math
import os
import sys
import threading
import time

# Must be set before pymavlink is imported: SADE-SIM drones speak MAVLink 2 (as PX4 does).
os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink

# The mission of examples/quickstart.yaml: (latitude, longitude, height above home in m,
# hold s).
TAKEOFF_M = 30.0
SPEED_MPS = 8.0
WAYPOINTS = [
    (41.8827, -87.6233, 40.0, 0.0),  # Cloud Gate ("The Bean")
    (41.8816, -87.6240, 40.0, 3.0),  # Crown Fountain, hold 3 s
    (41.8815, -87.6212, 40.0, 0.0),  # Lurie Garden
]
# Wall-clock limits (the scenario's clock may run faster than real time).
READY_TIMEOUT_S = 60
FLIGHT_TIMEOUT_S = 600


class PilotError(Exception):
    pass


def url_for_pymavlink(url):
    """Fleet-file URLs use MAVSDK's syntax (`udpout://127.0.0.1:24600`); pymavlink wants
    `udpout:127.0.0.1:24600` (and `tcp:` for `tcpout://`)."""
    scheme, _, address = url.partition("://")
    return {"tcpout": "tcp"}.get(scheme, scheme) + ":" + address


class Drone:
    """One drone's MAVLink connection, with the ground station's 1 Hz heartbeat."""

    def __init__(self, info):
        self.name = info["name"]
        self.sysid = info["systemId"]
        self.home = info["home"]
        # udpout: we speak first (our heartbeat), then the drone sends us its telemetry.
        self.link = mavutil.mavlink_connection(
            url_for_pymavlink(info["mavlink"]["udp"]), source_system=255, source_component=190
        )
        self.next_heartbeat = 0.0

    def log(self, text):
        print(f"{self.name}: {text}", flush=True)

    def recv(self, types, timeout_s):
        """The next message of one of `types` from our drone, or None after `timeout_s`."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if time.monotonic() >= self.next_heartbeat:
                self.link.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                self.next_heartbeat = time.monotonic() + 1.0
            msg = self.link.recv_match(type=types + ["STATUSTEXT"], blocking=True, timeout=0.2)
            if msg is None or msg.get_srcSystem() != self.sysid:
                continue
            if msg.get_type() == "STATUSTEXT":
                self.log(f"says: {msg.text}")
                continue
            return msg
        return None

    def wait_ready(self):
        """Heartbeat, a 3D GNSS fix and a home position: the drone can arm."""
        if self.recv(["HEARTBEAT"], READY_TIMEOUT_S) is None:
            raise PilotError("no heartbeat")
        if self.recv(["GPS_RAW_INT"], READY_TIMEOUT_S) is None:
            raise PilotError("no GPS_RAW_INT")
        deadline = time.monotonic() + READY_TIMEOUT_S
        while (msg := self.recv(["GPS_RAW_INT"], 2)) is None or msg.fix_type < 3:
            if time.monotonic() > deadline:
                raise PilotError("no 3D GNSS fix")
        self.log("ready (heartbeat, 3D fix)")

    def mission_items(self):
        """MISSION_ITEM_INT fields: takeoff, cruise speed, waypoints, return to launch."""
        lat, lon = self.home["latitudeDeg"], self.home["longitudeDeg"]
        rel = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        items = [
            (mavlink.MAV_CMD_NAV_TAKEOFF, rel, (0, 0, 0, math.nan), lat, lon, TAKEOFF_M),
            (mavlink.MAV_CMD_DO_CHANGE_SPEED, mavlink.MAV_FRAME_MISSION, (1, SPEED_MPS, -1, 0), 0, 0, 0),
        ]
        for wlat, wlon, height_m, hold_s in WAYPOINTS:
            items.append((mavlink.MAV_CMD_NAV_WAYPOINT, rel, (hold_s, 0, 0, math.nan), wlat, wlon, height_m))
        items.append((mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION, (0, 0, 0, 0), 0, 0, 0))
        return items

    def upload_mission(self):
        """The MAVLink mission protocol: MISSION_COUNT, the drone asks for each item with
        MISSION_REQUEST_INT, and ends with MISSION_ACK."""
        items = self.mission_items()
        self.link.mav.mission_count_send(self.sysid, 1, len(items), mavlink.MAV_MISSION_TYPE_MISSION)
        while True:
            msg = self.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], 5)
            if msg is None:
                raise PilotError("mission upload: the drone stopped asking for items")
            if msg.get_type() == "MISSION_ACK":
                if msg.type != mavlink.MAV_MISSION_ACCEPTED:
                    raise PilotError(f"mission upload refused: MAV_MISSION_RESULT {msg.type}")
                self.log(f"mission of {len(items)} items uploaded")
                return
            command, frame, (p1, p2, p3, p4), lat, lon, alt = items[msg.seq]
            self.link.mav.mission_item_int_send(
                self.sysid, 1, msg.seq, frame, command, 0, 1, p1, p2, p3, p4,
                int(round(lat * 1e7)), int(round(lon * 1e7)), alt, mavlink.MAV_MISSION_TYPE_MISSION,
            )

    def command(self, command, *params):
        """COMMAND_LONG; returns the COMMAND_ACK result."""
        p = list(params) + [0] * (7 - len(params))
        self.link.mav.command_long_send(self.sysid, 1, command, 0, *p)
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            ack = self.recv(["COMMAND_ACK"], 1)
            if ack is not None and ack.command == command:
                return ack.result
        raise PilotError(f"no COMMAND_ACK for command {command}")

    def arm(self):
        deadline = time.monotonic() + READY_TIMEOUT_S
        while (result := self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)) != mavlink.MAV_RESULT_ACCEPTED:
            if time.monotonic() > deadline:
                raise PilotError(f"arming refused (MAV_RESULT {result})")
            time.sleep(1)  # e.g. the position estimate is not good enough yet
        self.log("armed")

    def fly(self):
        self.wait_ready()
        self.upload_mission()
        self.arm()
        result = self.command(mavlink.MAV_CMD_MISSION_START, 0, 0)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise PilotError(f"MISSION_START refused (MAV_RESULT {result})")
        self.log("mission started")
        # Follow the flight until the drone has been in the air, landed and disarmed.
        deadline = time.monotonic() + FLIGHT_TIMEOUT_S
        airborne = False
        current = None
        while time.monotonic() < deadline:
            msg = self.recv(["HEARTBEAT", "EXTENDED_SYS_STATE", "MISSION_CURRENT"], 5)
            if msg is None:
                raise PilotError("lost contact (no message for 5 s)")
            kind = msg.get_type()
            if kind == "MISSION_CURRENT" and msg.seq != current:
                current = msg.seq
                self.log(f"mission item {current}")
            elif kind == "EXTENDED_SYS_STATE" and msg.landed_state == mavlink.MAV_LANDED_STATE_IN_AIR:
                airborne = True
            elif kind == "HEARTBEAT":
                armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
                if airborne and not armed:
                    self.log("landed and disarmed")
                    return
        raise PilotError(f"still flying after {FLIGHT_TIMEOUT_S} s")


def main():
    fleet_path = os.environ.get("SADESIM_FLEET")
    if not fleet_path:
        sys.exit("SADESIM_FLEET is not set: run this pilot through `sadesim run`, or point it at a run's fleet.json")
    with open(fleet_path, encoding="utf-8") as f:
        fleet = json.load(f)
    # Drones flown by a scripted mission (`scripted: true`) are left alone.
    infos = [d for d in fleet["drones"] if not d["scripted"]]
    print(f"run {fleet['run']}: flying {len(infos)} drones", flush=True)

    failures = {}

    def fly(info):
        drone = None
        try:
            drone = Drone(info)
            drone.fly()
        except Exception as e:  # report every drone's failure, not just the first
            failures[info["name"]] = f"{type(e).__name__}: {e}" if not isinstance(e, PilotError) else str(e)
        finally:
            if drone is not None:
                drone.link.close()

    threads = [threading.Thread(target=fly, args=(info,), name=info["name"]) for info in infos]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if failures:
        for name, reason in sorted(failures.items()):
            print(f"FAILED {name}: {reason}", file=sys.stderr, flush=True)
        sys.exit(1)
    print(f"all {len(infos)} drones landed", flush=True)


if __name__ == "__main__":
    main()
