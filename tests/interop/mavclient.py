"""A small pymavlink ground-station client for the interop tests: deadlines instead of
sleeps, a GCS heartbeat once a second (so `udpout` endpoints and routers know us), and
messages filtered by the sender's system id."""
import os
import time

os.environ["MAVLINK20"] = "1"  # before pymavlink is imported: MAVLink 2 framing
from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink

GCS_SYSTEM_ID = 255
GCS_COMPONENT_ID = 190  # MAV_COMP_ID_MISSIONPLANNER


class Client:
    """One pymavlink connection (`udpout:127.0.0.1:24600`, `tcp:127.0.0.1:5760`, ...).

    With `signing_key` (32 bytes, e.g. `hashlib.sha256(passphrase).digest()`) every frame is
    signed from the first heartbeat on, and pymavlink drops received frames that are not
    signed with that key."""

    def __init__(self, url: str, system_id: int = GCS_SYSTEM_ID, signing_key: bytes | None = None):
        self.url = url
        self.conn = mavutil.mavlink_connection(
            url, source_system=system_id, source_component=GCS_COMPONENT_ID, autoreconnect=False
        )
        if signing_key is not None:
            self.conn.setup_signing(signing_key, sign_outgoing=True)
        self._next_heartbeat = 0.0
        self.heartbeat()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def close(self):
        self.conn.close()

    @property
    def mav(self):
        return self.conn.mav

    def heartbeat(self):
        self.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE)
        self._next_heartbeat = time.monotonic() + 1.0

    def recv(self, timeout_s: float = 0.2):
        """The next message (any sender), or None after `timeout_s`. Keeps heartbeating."""
        if time.monotonic() >= self._next_heartbeat:
            self.heartbeat()
        msg = self.conn.recv_match(blocking=True, timeout=timeout_s)
        if msg is not None and msg.get_type() == "BAD_DATA":
            return None
        return msg

    def messages(self, timeout_s: float):
        """Yields every message received for `timeout_s`."""
        deadline = time.monotonic() + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            msg = self.recv(min(0.2, left))
            if msg is not None:
                yield msg

    def wait(self, msg_type: str, timeout_s: float, what: str, source: int | None = None, where=lambda m: True):
        """The first `msg_type` message from system `source` (any if None) for which
        `where(msg)` holds; AssertionError naming `what` after `timeout_s`."""
        for msg in self.messages(timeout_s):
            if msg.get_type() == msg_type and (source is None or msg.get_srcSystem() == source) and where(msg):
                return msg
        raise AssertionError(f"{self.url}: no {msg_type} within {timeout_s:.0f} s: {what}")

    def command_long(self, target: int, command: int, *params: float, confirmation: int = 0):
        p = list(params) + [0.0] * (7 - len(params))
        self.mav.command_long_send(target, 1, command, confirmation, *p)

    def command_ack(self, target: int, command: int, timeout_s: float = 5.0):
        """COMMAND_LONG `command` to `target`, returns its COMMAND_ACK."""
        self.command_long(target, command)
        return self.wait(
            "COMMAND_ACK", timeout_s, f"COMMAND_ACK for command {command}", source=target, where=lambda m: m.command == command
        )

    def param_read(self, target: int, name: str, timeout_s: float = 5.0):
        """PARAM_REQUEST_READ by name; returns the PARAM_VALUE."""
        self.mav.param_request_read_send(target, 1, name.encode(), -1)
        return self.wait("PARAM_VALUE", timeout_s, f"PARAM_VALUE {name}", source=target, where=lambda m: m.param_id == name)

    def send_raw(self, data: bytes):
        """Bytes exactly as given (UDP: one datagram)."""
        self.conn.write(data)


def frame(msg, system_id: int = GCS_SYSTEM_ID, component_id: int = GCS_COMPONENT_ID, seq: int = 0) -> bytes:
    """The MAVLink 2 frame of a pymavlink message object, e.g.
    `frame(mavlink.MAVLink_param_request_read_message(1, 1, b"SYS_AUTOSTART", -1))`."""
    mav = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
    mav.seq = seq
    return bytes(msg.pack(mav))


def with_bad_crc(data: bytes) -> bytes:
    """The same frame with its checksum (last two bytes of an unsigned frame) inverted."""
    return data[:-2] + bytes(b ^ 0xFF for b in data[-2:])
