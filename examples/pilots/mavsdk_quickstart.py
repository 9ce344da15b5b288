#!/usr/bin/env python3
"""A SADE-SIM pilot written with MAVSDK: every drone of the fleet takes off to 30 m, flies
three waypoints at 40 m over Millennium Park and returns to launch.

Run it through a scenario (it is started when all drones are ready):

    sadesim run examples/quickstart-mavsdk.yaml

or by hand against a run started with --no-pilot:

    SADESIM_FLEET=runs/quickstart-mavsdk/<time>/fleet.json python3 examples/pilots/mavsdk_quickstart.py

One program flies all drones: one MAVSDK instance and System per drone, each listening on
the drone's API link (`mavlink.api` in the fleet file: `udpin://0.0.0.0:14540` for drone 0,
exactly as with PX4 SITL), all driven concurrently with asyncio. Exits 0 when every drone
has landed and disarmed, 1 otherwise.

Needs `pip install mavsdk` (4.x: the native binding, the MAVSDK core ships in the wheel and
no mavsdk_server is needed).
"""
import asyncio
import json
import os
import sys

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.mission import MissionAsync, MissionItem, MissionPlan
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

TAKEOFF_M = 30.0
SPEED_MPS = 8.0
# (latitude, longitude, height above home in m, stop there): the waypoints of
# quickstart.yaml. MAVSDK stops 0.5 s at a waypoint that is not "fly through". (Its
# `loiter_time_s` adds a MAV_CMD_NAV_DELAY item, which SADE-SIM missions do not support
# yet: see docs/pilots.md.)
WAYPOINTS = [
    (41.8827, -87.6233, 40.0, False),  # Cloud Gate ("The Bean")
    (41.8816, -87.6240, 40.0, True),  # Crown Fountain
    (41.8815, -87.6212, 40.0, False),  # Lurie Garden
]
# Wall-clock limits (the scenario's clock may run faster than real time).
READY_TIMEOUT_S = 60
FLIGHT_TIMEOUT_S = 600


async def wait_for(what, check, timeout_s, poll_s=0.5):
    """Polls the coroutine function `check` until it returns True."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not await check():
        if loop.time() > deadline:
            raise RuntimeError(f"timed out after {timeout_s} s waiting for {what}")
        await asyncio.sleep(poll_s)


async def fly(info):
    name = info["name"]

    def log(text):
        print(f"{name}: {text}", flush=True)

    # Each drone gets its own MAVSDK instance; `mavlink.udp` (udpout://127.0.0.1:24600+i)
    # works as well, and across machines.
    mavsdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        await mavsdk.add_any_connection(info["mavlink"]["api"])
        drone = await mavsdk.first_autopilot(timeout_s=READY_TIMEOUT_S)
        if drone is None:
            raise RuntimeError(f"no autopilot on {info['mavlink']['api']}")
        action, mission, telemetry = ActionAsync(drone), MissionAsync(drone), TelemetryAsync(drone)

        async def ready():
            health = await telemetry.health()
            return health.is_global_position_ok and health.is_home_position_ok

        await wait_for("a GNSS fix and a home position", ready, READY_TIMEOUT_S)
        log("ready")

        items = [
            MissionItem(latitude_deg=lat, longitude_deg=lon, relative_altitude_m=height, speed_m_s=SPEED_MPS,
                        is_fly_through=not stop)
            for lat, lon, height, stop in WAYPOINTS
        ]
        await mission.set_return_to_launch_after_mission(True)  # appends a return-to-launch item
        await mission.upload_mission(MissionPlan(items))
        log(f"mission of {len(items)} waypoints uploaded")

        await action.set_takeoff_altitude(TAKEOFF_M)
        await action.arm()
        await action.takeoff()
        log(f"taking off to {TAKEOFF_M:.0f} m")

        async def at_takeoff_altitude():
            return (await telemetry.position()).relative_altitude_m > TAKEOFF_M - 1.0

        await wait_for("the takeoff altitude", at_takeoff_altitude, FLIGHT_TIMEOUT_S)
        await mission.start_mission()
        log("mission started")

        reported = None

        async def landed():
            nonlocal reported
            progress = await mission.mission_progress()
            if (progress.current, progress.total) != reported:
                reported = (progress.current, progress.total)
                log(f"mission item {progress.current}/{progress.total}")
            return not await telemetry.in_air() and not await telemetry.armed()

        await wait_for("landing back home", landed, FLIGHT_TIMEOUT_S)
        log("landed and disarmed")
    finally:
        mavsdk.destroy()


async def main():
    fleet_path = os.environ.get("SADESIM_FLEET")
    if not fleet_path:
        sys.exit("SADESIM_FLEET is not set: run this pilot through `sadesim run`, or point it at a run's fleet.json")
    with open(fleet_path, encoding="utf-8") as f:
        fleet = json.load(f)
    # Drones flown by a scripted mission (`scripted: true`) are left alone.
    infos = [d for d in fleet["drones"] if not d["scripted"]]
    print(f"run {fleet['run']}: flying {len(infos)} drones", flush=True)

    results = await asyncio.gather(*(fly(info) for info in infos), return_exceptions=True)
    failed = [(info["name"], r) for info, r in zip(infos, results) if isinstance(r, BaseException)]
    for name, error in failed:
        print(f"FAILED {name}: {type(error).__name__}: {error}", file=sys.stderr, flush=True)
    if failed:
        sys.exit(1)
    print(f"all {len(infos)} drones landed", flush=True)


if __name__ == "__main__":
    asyncio.run(main())
