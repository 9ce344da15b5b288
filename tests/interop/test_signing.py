"""MAVLink 2 signing on the router's ground-station side (`spec.groundStations.signing`),
with pymavlink as users run it: `setup_signing(sha256(passphrase))`.

Each test runs against both ways `sadesim run` starts the router: on a thread of its own
process (the passphrase handed over in memory) and as a `sim-worker router` process
(`--processes`, the passphrase in SADESIM_MAVLINK_SIGNING_KEY). The MAVLink ports are fixed:
these tests must not run in parallel with each other or with any other run using MAVLink
(see simrun.py).
"""
import hashlib
import re

import pytest

from mavclient import Client, mavlink
from simrun import pymavlink_url, scenario, wait_until

PASSPHRASE = "interop signing passphrase"
KEY = hashlib.sha256(PASSPHRASE.encode()).digest()
WRONG_KEY = hashlib.sha256(b"not the run's passphrase").digest()


@pytest.fixture(scope="module", params=["threads", "processes"])
def run(request, start_run, sim_worker):
    doc = scenario(f"interop-signing-{request.param}")
    doc["spec"]["groundStations"] = {"signing": {"key": {"value": PASSPHRASE}}}
    args = ["--processes"] if request.param == "processes" else []
    with start_run(doc, *args) as r:
        yield r


def router_log(run) -> str:
    """What the router wrote on stderr: sadesim's own output when it runs the router on a
    thread, `router-0.log` in the run folder when it runs `sim-worker router`."""
    text = run.log_path.read_text(errors="replace")
    router = run.out_dir / "router-0.log"
    if router.exists():
        text += router.read_text(errors="replace")
    return text


def local_port(client: Client) -> int:
    """The client's own UDP port: the source port the router sees."""
    return client.conn.port.getsockname()[1]


@pytest.mark.parametrize("transport", ["udp", "tcp"])
def test_a_client_with_the_passphrase_gets_signed_frames_and_answers(run, transport):
    url = pymavlink_url(run.fleet["gcsUrls"][0]) if transport == "udp" else "tcp:127.0.0.1:5760"
    sysid = run.drone(0)["systemId"]
    with Client(url, signing_key=KEY) as gcs:
        heartbeat = gcs.wait("HEARTBEAT", 15, "a HEARTBEAT through the signing router", source=sysid)
        assert heartbeat.get_signed(), "pymavlink with a key accepts only signed frames: this one must be"
        value = gcs.param_read(sysid, "MIS_TAKEOFF_ALT")
        assert value.get_signed()
        gcs.command_long(sysid, mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        version = gcs.wait("AUTOPILOT_VERSION", 5, "REQUEST_MESSAGE answered", source=sysid)
        assert version.get_signed()
        signing = gcs.mav.signing
        assert signing.goodsig_count > 0 and signing.badsig_count == 0, (
            f"{signing.goodsig_count} good and {signing.badsig_count} bad signatures"
        )


@pytest.mark.parametrize("key, reason", [(None, "unsigned"), (WRONG_KEY, "bad signature")], ids=["unsigned", "wrong-key"])
def test_a_client_without_the_passphrase_gets_no_answer_and_the_refusal_is_logged(run, key, reason):
    url = pymavlink_url(run.fleet["gcsUrls"][0])
    sysid = run.drone(0)["systemId"]
    with Client(url, signing_key=key) as gcs:
        port = local_port(gcs)
        gcs.mav.param_request_read_send(sysid, 1, b"MIS_TAKEOFF_ALT", -1)
        gcs.command_long(sysid, mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        received = [m.get_type() for m in gcs.messages(4)]
    # Not even telemetry: only a sender of a validly signed frame becomes a client.
    assert not received, f"the router answered a client without the passphrase: {sorted(set(received))}"
    line = re.compile(rf"refused a frame from 127\.0\.0\.1:{port}: {reason}")
    wait_until(lambda: line.search(router_log(run)), 5, lambda: f"no '{line.pattern}' in the router's log:\n{router_log(run)[-3000:]}")
