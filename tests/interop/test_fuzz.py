"""30 s of garbage at the MAVLink sockets of a run: random bytes, truncated and corrupted
frames, as UDP datagrams and TCP streams, to the drone endpoints and the router. The
simulation must keep its pace and the drones must keep answering.

Traffic goes to 127.0.0.1 only, bounded in time (FUZZ_S) and rate (one send per
~1 ms). The MAVLink ports are fixed: this test must not run in parallel with the other
interop tests or any other run using MAVLink (see simrun.py).
"""
import os
import random
import socket
import time

import pytest

from mavclient import Client, frame, mavlink
from simrun import REALTIME, port_of, pymavlink_url, scenario

FUZZ_S = 30.0
SEED = int(os.environ.get("SADESIM_FUZZ_SEED", "20261122"))
ROUTER_UDP, ROUTER_TCP = 14550, 5760


@pytest.fixture(scope="module")
def run(start_run):
    with start_run(scenario("interop-fuzz", drones=2, clock=REALTIME)) as r:
        yield r


def sample_frames(sysid: int) -> list[bytes]:
    """Well-formed frames of the kinds a drone parses (commands, params, missions,
    setpoints), to be cut and corrupted. Harmless even if one survived intact: a parameter
    read, a message-interval query, a mission count request, a heartbeat."""
    messages = [
        mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3),
        mavlink.MAVLink_param_request_read_message(sysid, 1, b"MPC_XY_CRUISE", -1),
        mavlink.MAVLink_param_request_list_message(sysid, 1),
        mavlink.MAVLink_command_long_message(sysid, 1, mavlink.MAV_CMD_GET_MESSAGE_INTERVAL, 0, 33, 0, 0, 0, 0, 0, 0),
        mavlink.MAVLink_mission_request_list_message(sysid, 1, 0),
        mavlink.MAVLink_timesync_message(0, 123456789),
    ]
    return [frame(m, seq=i) for i, m in enumerate(messages)]


def mutate(rng: random.Random, good: list[bytes]) -> bytes:
    base = bytearray(rng.choice(good))
    kind = rng.randrange(6)
    if kind == 0:  # random bytes
        return rng.randbytes(rng.randint(1, 600))
    if kind == 1:  # truncated anywhere
        return bytes(base[: rng.randint(1, len(base) - 1)])
    if kind == 2:  # bit flips (the checksum catches them)
        for _ in range(rng.randint(1, 4)):
            base[rng.randrange(len(base))] ^= 1 << rng.randrange(8)
        return bytes(base)
    if kind == 3:  # a lying length byte
        base[1] = rng.randrange(256)
        return bytes(base)
    if kind == 4:  # start bytes everywhere: v2, v1, inside random noise
        noise = bytearray(rng.randbytes(rng.randint(10, 300)))
        for _ in range(rng.randint(1, 10)):
            noise[rng.randrange(len(noise))] = rng.choice((0xFD, 0xFE))
        return bytes(noise)
    # signed-frame flag with no signature, unknown message id, wrong checksum
    base[2] |= 0x01
    base[7:10] = rng.randbytes(3)
    return bytes(base)


def tcp_connect(port: int) -> socket.socket | None:
    try:
        s = socket.create_connection(("127.0.0.1", port), timeout=1)
        s.settimeout(0.05)
        return s
    except OSError:
        return None


def test_fuzzing_the_sockets_stops_neither_the_clock_nor_the_drones(run):
    rng = random.Random(SEED)
    drones = run.fleet["drones"]
    udp_ports = [port_of(d["mavlink"]["udp"]) for d in drones] + [ROUTER_UDP]
    tcp_ports = [port_of(d["mavlink"]["tcp"]) for d in drones] + [ROUTER_TCP]
    good = [f for d in drones for f in sample_frames(d["systemId"])]
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    streams: dict[int, socket.socket | None] = {p: tcp_connect(p) for p in tcp_ports}
    sent = {"udp": 0, "tcp": 0, "tcp_reconnects": 0}

    sim_start, wall_start = run.sim_time_s(), time.monotonic()
    try:
        while time.monotonic() - wall_start < FUZZ_S:
            data = mutate(rng, good)
            if rng.random() < 0.7:
                udp.sendto(data, ("127.0.0.1", rng.choice(udp_ports)))
                sent["udp"] += 1
            else:
                port = rng.choice(tcp_ports)
                s = streams.get(port)
                if s is None or rng.random() < 0.01:  # now and then a fresh connection
                    if s is not None:
                        s.close()
                    s = streams[port] = tcp_connect(port)
                    sent["tcp_reconnects"] += 1
                if s is not None:
                    try:
                        s.sendall(data)
                        sent["tcp"] += 1
                        s.recv(65536)  # drain telemetry now and then so the peer is not stalled
                    except (socket.timeout, BlockingIOError):
                        pass
                    except OSError:
                        s.close()
                        streams[port] = None
            time.sleep(0.001)
        assert run.alive(), f"sadesim died while fuzzed ({sent})\n{run.log_tail()}"
        sim_end, wall_end = run.sim_time_s(), time.monotonic()
    finally:
        udp.close()
        for s in streams.values():
            if s is not None:
                s.close()

    rate = (sim_end - sim_start) / (wall_end - wall_start)
    print(f"fuzz: seed {SEED}, sent {sent}, simulated time at {rate:.2f}x wall time")
    expected = run.clock_factor
    assert 0.5 * expected <= rate <= 1.5 * expected, (
        f"simulated time advanced at {rate:.2f}x wall time during the fuzzing, expected {expected}x +-50% "
        f"(trajectory.csv time_s {sim_start:.1f} -> {sim_end:.1f} s); sent {sent}, seed {SEED}"
    )

    # Every drone still answers, over UDP and TCP, and so does the router.
    for d in drones:
        for url in (d["mavlink"]["udp"], d["mavlink"]["tcp"]):
            with Client(pymavlink_url(url)) as client:
                client.wait("HEARTBEAT", 10, f"heartbeat from drone {d['index']} after fuzzing", source=d["systemId"])
                value = client.param_read(d["systemId"], "MPC_XY_CRUISE")
                assert value.param_value > 0
    with Client(pymavlink_url(run.fleet["gcsUrls"][0])) as gcs:
        for d in drones:
            gcs.wait("HEARTBEAT", 10, f"drone {d['index']} through the router after fuzzing", source=d["systemId"])
        ack = gcs.command_ack(drones[1]["systemId"], 50123)
        assert ack.result == mavlink.MAV_RESULT_UNSUPPORTED
    # And the clock still runs after the storm.
    before = run.sim_time_s()
    time_now = time.monotonic()
    t = run.sim_time_s()
    while t - before < 1.0 and time.monotonic() - time_now < 10:
        time.sleep(0.1)
        t = run.sim_time_s()
    assert t - before >= 1.0, f"simulated time stuck at {t:.1f} s after the fuzzing"
