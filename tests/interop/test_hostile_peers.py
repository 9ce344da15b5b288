"""Hostile MAVLink peers against a real run (issue 40, item 5): a pilot that floods a drone
with commands, and a ground station that sends the router garbage. Each gets a clear
refusal, and the rest of the run goes on: the other drone flies, the flooded drone still
answers a well-behaved peer, and the run ends with its evidence (SimRun's exit checks).

The MAVLink ports are fixed: these tests must not run in parallel with each other or with
any other run using MAVLink (see simrun.py).
"""
import pathlib
import socket
import time

import pytest

from mavclient import Client, frame, mavlink
from simrun import REALTIME, port_of, pymavlink_url, scenario, wait_until

ROUTER_UDP = 14550
FLOODER_SYSID = 77
FLOOD_S = 3.0


@pytest.fixture(scope="module")
def run(start_run):
    with start_run(scenario("interop-hostile", drones=2, clock=REALTIME)) as r:
        yield r


def rss_mb(pid: int) -> float:
    for line in pathlib.Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


def flood_datagram(target: int) -> tuple[bytes, int]:
    """About 1 400 bytes of commands, mode changes and mission items for `target` (what a
    pilot stuck in a loop would send), and how many frames that is."""
    messages = [
        mavlink.MAVLink_command_long_message(target, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, 1, 4, 3, 0, 0, 0, 0),
        mavlink.MAVLink_set_mode_message(target, 1, 4 << 16 | 3 << 24),
        mavlink.MAVLink_mission_item_int_message(target, 1, 5, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                                 mavlink.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, 0, 418_818_000,
                                                 -876_226_000, 30, 0),
    ]
    out = b""
    seq = 0
    while len(out) < 1400:
        out += frame(messages[seq % len(messages)], system_id=FLOODER_SYSID, seq=seq % 256)
        seq += 1
    return out, seq


def take_off(client: Client, target: int):
    """Arms (retried while the arming checks wait for a fix) and takes off to MIS_TAKEOFF_ALT
    (2.5 m)."""
    deadline = time.monotonic() + 30
    while True:
        client.command_long(target, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        ack = client.wait("COMMAND_ACK", 5, "arming", source=target,
                          where=lambda m: m.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM)
        if ack.result == mavlink.MAV_RESULT_ACCEPTED:
            break
        assert time.monotonic() < deadline, f"arming refused with {ack.result} for 30 s"
        time.sleep(1)
    client.command_long(target, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, float("nan"), float("nan"), float("nan"),
                        float("nan"))
    ack = client.wait("COMMAND_ACK", 5, "takeoff", source=target,
                      where=lambda m: m.command == mavlink.MAV_CMD_NAV_TAKEOFF)
    assert ack.result == mavlink.MAV_RESULT_ACCEPTED, ack


def test_a_command_flood_is_cut_and_reported_and_the_rest_of_the_run_goes_on(run):
    victim, other = run.drone(0), run.drone(1)
    victim_id, other_id = victim["systemId"], other["systemId"]
    rss_before = rss_mb(run.proc.pid)
    flooder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    flooder.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    flooder.bind(("127.0.0.1", 0))
    endpoint = ("127.0.0.1", port_of(victim["mavlink"]["udp"]))
    datagram, frames_per_datagram = flood_datagram(victim_id)
    sent = 0
    with Client(pymavlink_url(other["mavlink"]["udp"])) as pilot, \
            Client(pymavlink_url(victim["mavlink"]["udp"])) as gcs:
        start = time.monotonic()
        next_pump = start
        while time.monotonic() - start < FLOOD_S:
            for _ in range(20):
                flooder.sendto(datagram, endpoint)
                sent += 1
            time.sleep(0.002)
            if time.monotonic() >= next_pump:
                pilot.heartbeat()
                gcs.heartbeat()
                next_pump += 0.5
        flood_rate = sent * frames_per_datagram / FLOOD_S
        # The flooder was told, in the drone's telemetry to it.
        flooder.settimeout(0.5)
        told = None
        deadline = time.monotonic() + 10
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True
        while told is None and time.monotonic() < deadline:
            try:
                data = flooder.recv(65536)
            except socket.timeout:
                continue
            for msg in parser.parse_buffer(data) or []:
                if msg.get_type() == "STATUSTEXT" and "flood" in msg.text:
                    told = msg.text
        assert told == f"MAVLink flood from {FLOODER_SYSID}/190: dropping", \
            f"{told!r} after {sent} datagrams ({flood_rate:.0f} frames/s)"
        # The flooded drone still answers a well-behaved peer.
        value = gcs.param_read(victim_id, "MIS_TAKEOFF_ALT", timeout_s=10)
        assert value.param_value > 0
        # The other drone is flown as if nothing happened.
        take_off(pilot, other_id)
        # MIS_TAKEOFF_ALT is PX4's 2.5 m.
        wait_until(lambda: run.truth(1)["up"] > 1.5, 30, lambda: f"drone 1 did not climb: {run.truth(1)}")
    # The run's evidence names the flood, once, on the flooded drone.
    def flood_events():
        return [e for e in run.events() if e.get("event") == "commandRejected"
                and e.get("command") == f"mavlink:{FLOODER_SYSID}/190"]
    events = wait_until(flood_events, 15, lambda: f"no flood event in events.jsonl\n{run.log_tail()}")
    assert [e["drone"] for e in events] == [0], events
    assert events[0]["reason"].startswith("flood: over 2500 frames per simulated second"), events
    # Bounded: the flood did not pile up in the process (a generous bound; the session and
    # the endpoint keep fixed-size queues).
    grown = rss_mb(run.proc.pid) - rss_before
    assert grown < 100, f"sadesim grew by {grown:.0f} MB during the flood"
    assert run.alive()


def test_garbage_at_the_router_is_logged_once_naming_the_sender_and_the_byte(run):
    hostile = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    hostile.bind(("127.0.0.1", 0))
    port = hostile.getsockname()[1]
    garbage = b"GET /mavlink HTTP/1.1\r\nHost: sadesim\r\n\r\n" * 20
    for _ in range(500):
        hostile.sendto(garbage, ("127.0.0.1", ROUTER_UDP))
    # Another ground station is served all along.
    with Client(f"udpout:127.0.0.1:{ROUTER_UDP}") as gcs:
        gcs.wait("HEARTBEAT", 10, "telemetry through the router beside the garbage", source=run.drone(0)["systemId"])
        for _ in range(100):
            hostile.sendto(garbage, ("127.0.0.1", ROUTER_UDP))
        gcs.wait("HEARTBEAT", 10, "telemetry through the router after more garbage", source=run.drone(1)["systemId"])
    line = (f"MAVLink router, segment 0: dropped {len(garbage)} byte(s) from 127.0.0.1:{port} that are not MAVLink: "
            f"at byte 0 of a {len(garbage)}-byte datagram, byte 0x47 is no MAVLink start marker")

    def logged():
        lines = [ln for ln in run.log_path.read_text(errors="replace").splitlines() if f"127.0.0.1:{port}" in ln]
        return lines or None

    lines = wait_until(logged, 10, lambda: f"nothing logged about 127.0.0.1:{port}\n{run.log_tail()}")
    assert len(lines) == 1 and lines[0].startswith(line), lines
    assert run.alive()
