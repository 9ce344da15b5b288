"""MAVSDK (the C++ core through the `mavsdk` 4.x Python binding) flies one simulated drone
the way it flies PX4 SITL: connect on the API link (`udpin://0.0.0.0:14540`), health,
arm, takeoff, goto, a mission, offboard position setpoints, return to launch. After each
step the drone's *true* position in trajectory.csv must be where MAVSDK sent it.

The MAVLink ports are fixed: these tests must not run in parallel with each other or with
any other run using MAVLink (see simrun.py).
"""
import asyncio
import math
import time

import pytest
from mavsdk.asyncio import Autopilot, ComponentType, Configuration, Mavsdk
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.mission import MissionAsync, MissionItem, MissionPlan
from mavsdk.asyncio.plugins.offboard import OffboardAsync, PositionNedYaw
from mavsdk.asyncio.plugins.telemetry import FlightMode, TelemetryAsync

from simrun import describe_truth, enu_m, offset_deg, scaled, scenario

# Ground truth against the commanded target, m. The autopilot flies on its GNSS estimate
# (0.5 m noise, a slow bias) and PX4's acceptance radius, so a few metres, not centimetres.
TOLERANCE_M = 3.0
MISSION_TOLERANCE_M = 4.0


@pytest.fixture(scope="module")
def run(start_run):
    with start_run(scenario("interop-mavsdk", clock=scaled(2))) as r:
        yield r


async def until(get, ok, timeout_s: float, what: str, poll_s: float = 0.2):
    """Awaits `get()` until `ok(value)`; AssertionError with the last value after `timeout_s`."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = await get()
        if ok(value):
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not reached within {timeout_s:.0f} s; last value {value}")
        await asyncio.sleep(poll_s)


async def until_truth(run, ok, timeout_s: float, what: str):
    """Waits until drone 0's ground truth satisfies `ok(row)`; fails on a crash or timeout."""

    async def truth():
        row = run.truth(0)
        assert not row["crashed"], f"{what}: the drone crashed: {describe_truth(row)}"
        return row

    try:
        return await until(truth, ok, timeout_s, what)
    except AssertionError:
        raise AssertionError(f"{what}: ground truth never matched within {timeout_s:.0f} s; last {describe_truth(run.truth(0))}") from None


def near(row, east: float, north: float, up: float | None, tol: float) -> bool:
    ok = math.hypot(row["east"] - east, row["north"] - north) <= tol
    return ok and (up is None or abs(row["up"] - up) <= tol)


def settled(row) -> bool:
    return math.hypot(row["vel_east_mps"], row["vel_north_mps"]) < 1.0 and abs(row["vel_up_mps"]) < 0.5


def test_mavsdk_flies_every_step_to_ground_truth(run):
    asyncio.run(asyncio.wait_for(fly(run), timeout=900))


async def fly(run):
    drone = run.drone(0)
    home = drone["home"]
    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    mavsdk = Mavsdk(config)
    try:
        # -- connect: the PX4 SITL address, as MAVSDK's own examples use it -----------------
        assert drone["mavlink"]["api"] == "udpin://0.0.0.0:14540", drone["mavlink"]
        await mavsdk.add_any_connection(drone["mavlink"]["api"])
        system = await mavsdk.first_autopilot(timeout_s=30)
        assert system is not None, "MAVSDK found no autopilot on udpin://0.0.0.0:14540 within 30 s"
        assert await system.get_system_id() == drone["systemId"]
        assert await system.autopilot_type() == Autopilot.PX4, "MAVSDK must recognise the drone as PX4"
        action, mission = ActionAsync(system), MissionAsync(system)
        offboard, telemetry = OffboardAsync(system), TelemetryAsync(system)

        # -- health: GNSS fix, home position, pre-arm checks -------------------------------
        await until(
            telemetry.health,
            lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_local_position_ok and h.is_armable,
            60,
            "health (global/home/local position ok, armable)",
        )
        home_est = await telemetry.home()
        east, north, _ = enu_m(home, home_est.latitude_deg, home_est.longitude_deg, 0.0)
        assert math.hypot(east, north) <= TOLERANCE_M, (
            f"HOME_POSITION {home_est.latitude_deg:.7f}, {home_est.longitude_deg:.7f} is not the fleet file's home {home}"
        )

        # -- arm and take off to 10 m --------------------------------------------------------
        await action.set_takeoff_altitude(10.0)
        assert await action.get_takeoff_altitude() == pytest.approx(10.0), "MIS_TAKEOFF_ALT did not stick"
        await action.set_return_to_launch_altitude(20.0)
        await action.arm()
        await until(telemetry.armed, bool, 10, "telemetry armed")
        await until_truth(run, lambda r: r["armed"], 10, "armed in ground truth")
        await action.takeoff()
        await until_truth(run, lambda r: near(r, 0, 0, 10, TOLERANCE_M) and settled(r), 60, "takeoff to 10 m above home")
        assert await telemetry.in_air(), "in_air after takeoff"

        # -- goto_location (DO_REPOSITION) 40 m away, 15 m up --------------------------------
        goto = (24.0, 32.0, 15.0)  # east, north, up from home, m: 40 m horizontally
        lat, lon = offset_deg(home, goto[0], goto[1])
        await action.goto_location(lat, lon, home["altitudeMslM"] + goto[2], 0.0)
        await until_truth(run, lambda r: near(r, *goto, TOLERANCE_M) and settled(r), 60, f"goto_location {goto}")

        # -- a 3-waypoint mission -----------------------------------------------------------------
        waypoints = [(-20.0, 30.0, 12.0), (-20.0, -20.0, 12.0), (20.0, -20.0, 12.0)]
        items = []
        for east, north, up in waypoints:
            wlat, wlon = offset_deg(home, east, north)
            items.append(MissionItem(latitude_deg=wlat, longitude_deg=wlon, relative_altitude_m=up, speed_m_s=5.0,
                                     is_fly_through=False, acceptance_radius_m=1.0, yaw_deg=float("nan")))
        await mission.set_return_to_launch_after_mission(False)
        await mission.upload_mission(MissionPlan(items))
        downloaded = await mission.download_mission()
        assert len(downloaded.mission_items) == 3, f"downloaded {len(downloaded.mission_items)} items, uploaded 3"
        await mission.start_mission()
        closest = [math.inf] * len(waypoints)
        deadline = time.monotonic() + 180
        while True:
            row = run.truth(0)
            assert not row["crashed"], f"crashed during the mission: {describe_truth(row)}"
            for k, (east, north, up) in enumerate(waypoints):
                closest[k] = min(closest[k], math.dist((row["east"], row["north"], row["up"]), (east, north, up)))
            progress = await mission.mission_progress()
            if progress.total == 3 and progress.current == 3 and await mission.is_mission_finished():
                break
            assert time.monotonic() < deadline, (
                f"mission not finished within 180 s: progress {progress.current}/{progress.total}, {describe_truth(row)}"
            )
            await asyncio.sleep(0.2)
        last = waypoints[-1]
        await until_truth(run, lambda r: near(r, *last, MISSION_TOLERANCE_M), 30, f"holding at the last waypoint {last}")
        for k, d in enumerate(closest):
            assert d <= MISSION_TOLERANCE_M, f"waypoint {k} {waypoints[k]}: passed no closer than {d:.1f} m"

        # -- offboard: position setpoints, 10 m north -----------------------------------------
        await until_truth(run, settled, 30, "settled before offboard")
        pv = (await telemetry.position_velocity_ned()).position
        target = (pv.east_m, pv.north_m + 10.0, -pv.down_m)  # east, north, up (LOCAL_POSITION_NED origin = home)
        # PX4 (and SADE-SIM) refuse OFFBOARD until setpoints are streaming: send one first.
        await offboard.set_position_ned(PositionNedYaw(pv.north_m, pv.east_m, pv.down_m, 0.0))
        await offboard.start()
        await until(telemetry.flight_mode, lambda m: m == FlightMode.OFFBOARD, 10, "flight mode OFFBOARD")
        await offboard.set_position_ned(PositionNedYaw(pv.north_m + 10.0, pv.east_m, pv.down_m, 0.0))
        await until_truth(run, lambda r: near(r, *target, TOLERANCE_M) and settled(r), 60, f"offboard setpoint {target}")
        await offboard.stop()

        # -- return to launch and land ----------------------------------------------------------
        await action.return_to_launch()
        await until(telemetry.in_air, lambda v: not v, 180, "landed (in_air False) after return_to_launch")
        await until(telemetry.armed, lambda v: not v, 30, "disarmed after landing")
        row = await until_truth(run, lambda r: r["on_ground"] and not r["armed"], 30, "on the ground, disarmed")
        assert near(row, 0, 0, None, TOLERANCE_M), f"landed away from home: {describe_truth(row)}"
    finally:
        mavsdk.destroy()

