"""The MAVLink router (in-process in `sadesim run`): 32 drones behind one ground-station
address, UDP 14550 and TCP 5760, as QGroundControl sees them.

The MAVLink ports are fixed: these tests must not run in parallel with each other or with
any other run using MAVLink (see simrun.py).
"""
import asyncio
import time

import pytest

from mavclient import Client, mavlink
from simrun import REALTIME, pymavlink_url, scenario

DRONES = 32


@pytest.fixture(scope="module")
def run(start_run):
    with start_run(scenario("interop-router", drones=DRONES, clock=REALTIME)) as r:
        yield r


@pytest.fixture(scope="module")
def sysids(run) -> set[int]:
    ids = {d["systemId"] for d in run.fleet["drones"]}
    assert len(ids) == DRONES, f"the fleet file gives {len(ids)} distinct system ids for {DRONES} drones"
    return ids


def gcs_udp(run) -> str:
    url = run.fleet["gcsUrls"][0]
    assert url == "udpout://127.0.0.1:14550", run.fleet["gcsUrls"]
    return pymavlink_url(url)


def heartbeat_sources(client: Client, want: set[int], timeout_s: float) -> set[int]:
    seen: set[int] = set()
    for msg in client.messages(timeout_s):
        if msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == 1:
            seen.add(msg.get_srcSystem())
            if want <= seen:
                break
    return seen


def test_udp_gcs_sees_every_drone_within_15_s(run, sysids):
    with Client(gcs_udp(run)) as gcs:
        seen = heartbeat_sources(gcs, sysids, 15)
    assert seen == sysids, f"missing system ids {sorted(sysids - seen)}, unexpected {sorted(seen - sysids)}"


@pytest.mark.parametrize(
    "command, param1",
    [
        (mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION),
        (mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_SYSTEM_TIME),
    ],
    ids=["REQUEST_MESSAGE", "SET_MESSAGE_INTERVAL"],
)
def test_targeted_command_is_answered_by_its_drone_only(run, sysids, command, param1):
    target = 7
    assert target in sysids
    with Client(gcs_udp(run)) as gcs:
        # Registered with the router (it saw our heartbeat) once telemetry flows back.
        gcs.wait("HEARTBEAT", 10, "telemetry through the router")
        # SET_MESSAGE_INTERVAL: SYSTEM_TIME at 2 Hz (500 000 us).
        gcs.command_long(target, command, param1, 500_000 if command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL else 0)
        acks = []
        for msg in gcs.messages(5):
            if msg.get_type() == "COMMAND_ACK" and msg.command == command:
                acks.append((msg.get_srcSystem(), msg.result))
    assert acks, f"no COMMAND_ACK for command {command} within 5 s"
    assert {src for src, _ in acks} == {target}, f"ACKs came from {sorted({s for s, _ in acks})}, only {target} was asked"
    assert all(result == mavlink.MAV_RESULT_ACCEPTED for _, result in acks), f"results {acks}"


def test_udp_and_tcp_clients_receive_telemetry_at_once(run, sysids):
    tcp_url = "tcp:127.0.0.1:5760"
    with Client(gcs_udp(run)) as udp, Client(tcp_url) as tcp:
        seen = {"udp": set(), "tcp": set()}
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and not (seen["udp"] >= sysids and seen["tcp"] >= sysids):
            for name, client in (("udp", udp), ("tcp", tcp)):
                msg = client.recv(0.05)
                if msg is not None and msg.get_type() == "GLOBAL_POSITION_INT":
                    seen[name].add(msg.get_srcSystem())
    for name in ("udp", "tcp"):
        missing = sorted(sysids - seen[name])
        assert not missing, f"the {name} GCS got no GLOBAL_POSITION_INT from {len(missing)} drones, e.g. {missing[:8]}"


def test_mavsdk_on_the_router_sees_every_drone_as_a_system(run, sysids):
    """One MAVSDK instance on the router's address gets one System per drone, as a
    multi-vehicle ground station would."""
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk

    async def discover() -> set[int]:
        mavsdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        try:
            await mavsdk.add_any_connection(run.fleet["gcsUrls"][0])
            found: set[int] = set()
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline and found != sysids:
                found = {await s.get_system_id() for s in await mavsdk.get_systems()}
                await asyncio.sleep(0.2)
            return found
        finally:
            mavsdk.destroy()

    found = asyncio.run(discover())
    assert found == sysids, f"MAVSDK found no System for {sorted(sysids - found)}"
