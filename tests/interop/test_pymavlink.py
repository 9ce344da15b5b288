"""pymavlink against one simulated drone's endpoint (`sadesim run --no-pilot`): the
parameter protocol, command acknowledgements, robustness to broken frames, and TCP.

The MAVLink ports are fixed: these tests must not run in parallel with each other or with
any other run using MAVLink (see simrun.py).
"""
import pytest

from mavclient import Client, frame, mavlink, with_bad_crc
from simrun import pymavlink_url, scenario


@pytest.fixture(scope="module")
def run(start_run):
    with start_run(scenario("interop-pymavlink")) as r:
        yield r


@pytest.fixture
def drone(run):
    """(client on the drone's UDP endpoint, the drone's system id)."""
    d = run.drone(0)
    with Client(pymavlink_url(d["mavlink"]["udp"])) as client:
        client.wait("HEARTBEAT", 10, "the drone answers a client that sends to its endpoint", source=d["systemId"])
        yield client, d["systemId"]


def test_heartbeat_says_px4_quadrotor(drone):
    client, sysid = drone
    hb = client.wait("HEARTBEAT", 5, "heartbeat", source=sysid)
    assert hb.autopilot == mavlink.MAV_AUTOPILOT_PX4, f"autopilot {hb.autopilot}, MAVSDK and QGC expect PX4 (12)"
    assert hb.type == mavlink.MAV_TYPE_QUADROTOR, f"type {hb.type}"
    assert hb.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, f"base_mode {hb.base_mode:#x}"
    assert hb.get_srcComponent() == 1, "the autopilot is component 1"


def test_parameter_list_completes_with_distinct_indices(drone):
    client, sysid = drone
    client.mav.param_request_list_send(sysid, 1)
    by_index: dict[int, str] = {}
    counts: set[int] = set()
    for msg in client.messages(30):
        if msg.get_type() != "PARAM_VALUE" or msg.get_srcSystem() != sysid:
            continue
        counts.add(msg.param_count)
        assert 0 <= msg.param_index < msg.param_count, f"{msg.param_id}: index {msg.param_index} of {msg.param_count}"
        previous = by_index.setdefault(msg.param_index, msg.param_id)
        assert previous == msg.param_id, f"index {msg.param_index} is both {previous} and {msg.param_id}"
        if len(by_index) == msg.param_count:
            break
    assert len(counts) == 1, f"param_count changed during the list: {sorted(counts)}"
    (count,) = counts
    missing = sorted(set(range(count)) - set(by_index))
    assert not missing, f"{len(missing)} of {count} parameters never arrived, e.g. indices {missing[:10]}"
    names = list(by_index.values())
    assert len(set(names)) == count, "parameter names must be unique"
    for expected in ("MIS_TAKEOFF_ALT", "MPC_XY_CRUISE", "RTL_RETURN_ALT", "SYS_AUTOSTART"):
        assert expected in names, f"{expected} missing from the PX4 parameter subset"


def test_param_set_reads_back(drone):
    client, sysid = drone
    original = client.param_read(sysid, "MIS_TAKEOFF_ALT")
    assert original.param_type == mavlink.MAV_PARAM_TYPE_REAL32
    try:
        client.mav.param_set_send(sysid, 1, b"MIS_TAKEOFF_ALT", 12.5, mavlink.MAV_PARAM_TYPE_REAL32)
        echo = client.wait(
            "PARAM_VALUE", 5, "PARAM_SET is answered with the new PARAM_VALUE", source=sysid,
            where=lambda m: m.param_id == "MIS_TAKEOFF_ALT",
        )
        assert echo.param_value == pytest.approx(12.5), f"PARAM_SET answered with {echo.param_value}"
        assert client.param_read(sysid, "MIS_TAKEOFF_ALT").param_value == pytest.approx(12.5)
    finally:
        client.mav.param_set_send(sysid, 1, b"MIS_TAKEOFF_ALT", original.param_value, mavlink.MAV_PARAM_TYPE_REAL32)
        client.wait("PARAM_VALUE", 5, "restore", source=sysid, where=lambda m: m.param_id == "MIS_TAKEOFF_ALT")


@pytest.mark.parametrize("command", [31000, 50123], ids=["in-dialect-31000", "outside-dialect-50123"])
def test_unknown_command_is_acked_unsupported(drone, command):
    client, sysid = drone
    if command == 50123:
        assert command not in mavlink.enums["MAV_CMD"], "pick a command id no dialect defines"
    ack = client.command_ack(sysid, command)
    assert ack.result == mavlink.MAV_RESULT_UNSUPPORTED, f"COMMAND_ACK result {ack.result}, expected UNSUPPORTED (3)"


def test_request_message_autopilot_version(drone):
    client, sysid = drone
    client.command_long(sysid, mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    version = client.wait("AUTOPILOT_VERSION", 5, "REQUEST_MESSAGE(AUTOPILOT_VERSION)", source=sysid)
    assert version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2, "MAVLink 2 capability bit"
    assert version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT, "MISSION_INT capability bit"


def test_broken_frames_are_ignored_and_the_drone_keeps_answering(drone):
    client, sysid = drone
    read = mavlink.MAVLink_param_request_read_message(sysid, 1, b"MPC_XY_CRUISE", -1)
    good = frame(read)
    broken = [
        b"\x00" * 64,  # no start byte at all
        b"\xfd",  # a lone start byte
        good[:7],  # truncated header
        good[:-5],  # truncated payload and checksum
        bytes([0xFD, 255]) + good[2:],  # length larger than the datagram
        b"\xfe\x09\x00\xff\xbe\x00" + b"\x01" * 9 + b"\x00\x00",  # MAVLink 1 heartbeat, bad checksum
        bytes(range(256)) * 4,  # a kilobyte of everything
    ]
    for data in broken:
        client.send_raw(data)
    # A well-formed request with a wrong checksum must be dropped, not answered.
    client.send_raw(with_bad_crc(good))
    for msg in client.messages(1.5):
        if msg.get_type() == "PARAM_VALUE" and msg.get_srcSystem() == sysid:
            raise AssertionError(f"a PARAM_REQUEST_READ with a wrong checksum was answered ({msg.param_id})")
    # Still alive: heartbeats keep coming and a good request is answered.
    client.wait("HEARTBEAT", 5, "heartbeats after broken frames", source=sysid)
    client.send_raw(good)
    client.wait("PARAM_VALUE", 5, "a valid request after broken frames", source=sysid,
                where=lambda m: m.param_id == "MPC_XY_CRUISE")
    # Frames glued to garbage in one datagram are still found.
    client.send_raw(b"garbage" + good + b"\xfd\x03")
    client.wait("PARAM_VALUE", 5, "a valid frame after garbage in the same datagram", source=sysid,
                where=lambda m: m.param_id == "MPC_XY_CRUISE")


def test_tcp_connection(run):
    d = run.drone(0)
    url = pymavlink_url(d["mavlink"]["tcp"])
    assert url == f"tcp:127.0.0.1:{24600 + d['index']}", url
    with Client(url) as client:
        client.wait("HEARTBEAT", 10, "heartbeats over TCP", source=d["systemId"])
        client.wait("GLOBAL_POSITION_INT", 10, "telemetry over TCP", source=d["systemId"])
        value = client.param_read(d["systemId"], "MIS_TAKEOFF_ALT")
        assert value.param_value > 0


def test_telemetry_set_of_a_px4_vehicle(run):
    """The messages MAVSDK and QGroundControl rely on arrive on the API link without asking."""
    d = run.drone(0)
    expected = {
        "HEARTBEAT", "SYS_STATUS", "GLOBAL_POSITION_INT", "LOCAL_POSITION_NED", "HOME_POSITION",
        "EXTENDED_SYS_STATE", "GPS_RAW_INT", "BATTERY_STATUS", "ATTITUDE", "ATTITUDE_QUATERNION",
        "VFR_HUD", "ALTITUDE",
    }
    seen: set[str] = set()
    with Client(pymavlink_url(d["mavlink"]["api"])) as client:
        for msg in client.messages(15):
            if msg.get_srcSystem() == d["systemId"]:
                seen.add(msg.get_type())
            if expected <= seen:
                break
    assert expected <= seen, f"missing on the API link within 15 s: {sorted(expected - seen)}"
