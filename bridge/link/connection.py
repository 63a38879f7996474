"""pymavlink links on the ground-station side: connection URLs, reading and sending, finding a vehicle.

Owns:
- pymavlink set-up for MAVLink 2 (MAVLINK20 must be set before pymavlink picks its dialect, or
  mission_type would be silently dropped);
- checking a pymavlink connection string (udpin:, udpout:, udp:, tcp:, tcpin:, a serial device with an
  optional baud) and a system id, raising BridgeUsageError for bad ones;
- Link: one connection with our GCS identity, optional signing, a 1 Hz GCS heartbeat, reads with a
  deadline, COMMAND_LONG with retries and its COMMAND_ACK, and per-vehicle boot-time tracking so a
  reboot is noticed;
- a lost transport: pymavlink prints "EOF on TCP socket" on every read of a closed TCP connection
  (and `select` wakes at once for it, so a read loop printed it a million times). Link takes those
  hooks over: it says once (log warning on "missionplan.bridge.link.connection") that the peer closed the connection,
  reconnects a bounded number of times, and otherwise raises one BridgeError. A serial device that
  vanishes (unplugged) is a BridgeError too; one that does not exist is a BridgeUsageError;
- several vehicles on one `udpin:` port (a fleet that all sends to one ground-station port): each
  datagram's sender is remembered per source system, and every packet we send goes to the address of
  the vehicle it is for (its target_system), not to the last sender; packets for no one in particular
  (our heartbeat) go to every vehicle heard. Sends are serialised (one lock around pack and write),
  so several threads may send on one Link (link.shared_link reads for them);
- wait_vehicle: the HEARTBEAT of the requested system (and component) and what it tells: the flavour;
- the signing diagnosis (Link.signing_hint): the one place that says whether MAVLink 2 signing is the
  likely reason a vehicle ignores us (it signs and we do not; or we sign and its packets are refused),
  which every "did not answer" message (parameters, mission transfers, commands) appends.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from missionplan.base.naming import Named

os.environ.setdefault("MAVLINK20", "1")  # before pymavlink is imported: MAVLink 2 dialect modules

from pymavlink import mavutil  # noqa: E402

from ..errors import BridgeError, BridgeUsageError  # noqa: E402
from ..formats.mission_items import Flavour  # noqa: E402
from .signing import SigningKey, apply_key, refused_packets  # noqa: E402

if mavutil.mavlink.WIRE_PROTOCOL_VERSION != "2.0":  # someone imported pymavlink before us without MAVLINK20
    os.environ["MAVLINK20"] = "1"
    mavutil.set_dialect(mavutil.current_dialect or "ardupilotmega")

mavlink: Any = mavutil.mavlink  # the MAVLink 2 dialect module (message classes and enums)

# Our identity on the link (--gcs-sysid / --gcs-compid). ArduPilot's GCS failsafe watches the heartbeat
# of system SYSID_MYGCS (default 255): another id is not "the" GCS for it; and two ground stations with
# one id (MAVProxy and us, both 255) get each other's mission-protocol replies.
GCS_SYSTEM_ID = 255  # a convention, not a MAVLink enum
GCS_COMPONENT_ID: int = mavlink.MAV_COMP_ID_MISSIONPLANNER
AUTOPILOT_COMPONENT_ID: int = mavlink.MAV_COMP_ID_AUTOPILOT1
REBOOT_JUMP = 0.25  # seconds; more than a late packet's delay, less than any reboot
# The messages whose time_boot_ms is when they were sent (a sample of a stream), so a clock that starts
# again in them means a reboot. Others carry the time of what they report (PX4: a setpoint's or a
# photo's time, SCALED_PRESSURE 0.17 s late on SIH), which may be seconds old: PX4 SIH was once taken
# for rebooted at its mission start.
CLOCK_MESSAGES = frozenset({"GLOBAL_POSITION_INT", "ATTITUDE", "LOCAL_POSITION_NED", "SYSTEM_TIME"})
COMMAND_TRIES = 5    # COMMAND_LONG sends before giving up
COMMAND_WAIT_S = 0.5  # for its COMMAND_ACK, each time
RECONNECT_TRIES = 4      # TCP connects after the peer closed the connection, before giving up
RECONNECT_WAIT_S = 0.5   # between them (and the connect time-out of each)
MAX_RECONNECTS = 5       # closed connections one Link survives; a peer that keeps dropping us is broken

log = logging.getLogger(__name__)

_HOST_PORT = re.compile(r"^(?P<host>[A-Za-z0-9_.\-]+|\[[0-9A-Fa-f:]+\]):(?P<port>\d{1,5})$")
_SERIAL = re.compile(r"^(/dev/\S+|COM\d+([,:]\S*)?)$", re.IGNORECASE)


@dataclass(frozen=True)
class ConnectionSpec:
    """A checked connection string: scheme (udpin, udpout, tcp, tcpin, serial), where, and baud."""

    scheme: str
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = 115200

    @property
    def url(self) -> str:
        if self.scheme == "serial":
            return f"{self.device},{self.baud}"
        return f"{self.scheme}:{self.host}:{self.port}"


def parse_url(url: str, setting: str = "connect", allow_any_port: bool = False) -> ConnectionSpec:
    """Check a pymavlink connection string; BridgeUsageError (one line) when it is not one we serve.

    setting: the setting the URL was given as (missionplan.base.naming), named by the error.
    allow_any_port: port 0 (let the system pick a free one) is allowed, for listening sockets.
    """
    text = (url or "").strip()
    if not text:
        raise BridgeUsageError(Named("{name}: empty connection string", name=setting))
    if _SERIAL.match(text):
        # DEVICE,BAUD (or DEVICE:BAUD): the baud is what follows the last comma, or the last colon
        # when the rest is not itself a device (/dev/serial/by-path/ names contain colons).
        device, baud_text = text, ""
        if "," in text:
            device, _, baud_text = text.rpartition(",")
        elif ":" in text and not os.path.exists(text) and text.rpartition(":")[2].isdigit():
            device, _, baud_text = text.rpartition(":")
        if baud_text and (not baud_text.isdigit() or int(baud_text) == 0):
            raise BridgeUsageError(Named("{name} {0}: bad baud rate {1!r}", url, baud_text, name=setting))
        return ConnectionSpec("serial", device=device, baud=int(baud_text or 115200))
    scheme, sep, rest = text.partition(":")
    if not sep or scheme not in ("udpin", "udpout", "udp", "tcp", "tcpin"):
        raise BridgeUsageError(Named("{name} {0}: not a connection string (use udpin:HOST:PORT, udpout:HOST:PORT, "
                                     "tcp:HOST:PORT, tcpin:HOST:PORT or a serial device such as /dev/ttyUSB0,57600)",
                                     url, name=setting))
    match = _HOST_PORT.match(rest)
    if not match:
        raise BridgeUsageError(Named("{name} {0}: expected {1}:HOST:PORT", url, scheme, name=setting))
    port = int(match.group("port"))
    if not (0 if allow_any_port else 1) <= port < 65536:
        raise BridgeUsageError(Named("{name} {0}: port {1} out of range", url, port, name=setting))
    return ConnectionSpec("udpin" if scheme == "udp" else scheme, host=match.group("host"), port=port)


def parse_sysid(value: str | int, setting: str = "sysid") -> int:
    """A vehicle system id: 1..254 (0 is broadcast, 255 is by convention a ground station)."""
    try:
        sysid = int(str(value).strip())
    except ValueError:
        raise BridgeUsageError(Named("{name} {0!r}: not a system id (an integer 1..254)", value,
                                     name=setting)) from None
    if not 1 <= sysid <= 254:
        raise BridgeUsageError(Named("{name} {0}: system ids run from 1 to 254", sysid, name=setting))
    return sysid


def parse_compid(value: str | int, setting: str = "compid") -> int:
    """A MAVLink component id: 1..255 (0 addresses every component)."""
    try:
        compid = int(str(value).strip())
    except ValueError:
        raise BridgeUsageError(Named("{name} {0!r}: not a component id (an integer 1..255)", value,
                                     name=setting)) from None
    if not 1 <= compid <= 255:
        raise BridgeUsageError(Named("{name} {0}: component ids run from 1 to 255", compid, name=setting))
    return compid


def parse_gcs_sysid(value: str | int, vehicles: list[int] | tuple[int, ...] = (),
                    setting: str = "gcs_sysid") -> int:
    """Our own system id on the link: 1..255 (255 by convention, what ArduPilot's SYSID_MYGCS expects),
    never one of the vehicles' (two systems with one id on a link cannot be told apart: replies and
    routing go by system id)."""
    try:
        sysid = int(str(value).strip())
    except ValueError:
        raise BridgeUsageError(Named("{name} {0!r}: not a system id (an integer 1..255)", value,
                                     name=setting)) from None
    if not 1 <= sysid <= 255:
        raise BridgeUsageError(Named("{name} {0}: system ids run from 1 to 255", sysid, name=setting))
    if sysid in vehicles:
        raise BridgeUsageError(Named("{name} {0}: that is a vehicle's system id; the ground station needs its own "
                                     "(default {1})", sysid, GCS_SYSTEM_ID, name=setting))
    return sysid


def parse_sysids(text: str, setting: str = "sysid") -> list[int]:
    """A comma-separated list of distinct system ids, such as "1,2,3"."""
    ids = [parse_sysid(part, setting) for part in str(text).split(",") if part.strip()]
    if not ids:
        raise BridgeUsageError(Named("{name}: no system id given", name=setting))
    if len(set(ids)) != len(ids):
        raise BridgeUsageError(Named("{name} {0}: a system id appears twice", text, name=setting))
    return ids


@dataclass(frozen=True)
class VehicleInfo:
    """What a vehicle's HEARTBEAT says about it."""

    sysid: int
    compid: int
    autopilot: int
    mav_type: int
    flavour: Flavour
    signed: bool  # its packets carry a MAVLink 2 signature


def is_signed(msg: Any) -> bool:
    """Whether a packet carried a signature (checked or not: without a key pymavlink does not check).

    Read from the header's incompat flags, not pymavlink's msg._signed: that is True only when a key
    was set and the signature checked, so it is False for every packet of a link without a key."""
    return bool(msg.get_header().incompat_flags & mavlink.MAVLINK_IFLAG_SIGNED)


class Link:
    """One pymavlink connection with our ground-station identity. Reads from one thread at a time;
    sends from any thread (link.shared_link shares one Link among several vehicles' threads)."""

    def __init__(self, url: str, key: SigningKey | None = None, source_system: int = GCS_SYSTEM_ID,
                 source_component: int = GCS_COMPONENT_ID) -> None:
        self.spec = parse_url(url)
        self.url = url
        self.key = key
        self._closed_by_peer = False
        self.reconnects = 0
        try:
            if self.spec.scheme == "serial":
                self.conn = _open_serial(self.spec, url, source_system, source_component)
            else:
                self.conn = mavutil.mavlink_connection(self.spec.url, source_system=source_system,
                                                       source_component=source_component, retries=0)
        except BridgeUsageError:
            raise
        except (OSError, ValueError) as err:
            detail = getattr(err, "strerror", None) or str(err)
            raise BridgeError(f"cannot open {url}: {detail}") from None
        if self.spec.scheme == "tcp":
            # pymavlink prints on every read of a closed socket; we notice, and say it once.
            self.conn.handle_eof = self.conn.handle_disconnect = self._peer_closed
        # Writes may come from several threads (the MAVSDK backend's pump and MAVSDK's own; fly's drone
        # threads on a shared link): one packet at a time, and packing (sequence number, signature) too.
        self.write_lock = threading.RLock()
        self.addresses: dict[int, Any] = {}  # udpin: where each system id's packets come from
        self._send_to: int = 0  # udpin: target_system of the packet being written (0: everyone)
        self._datagrams: deque[tuple[Any, Any]] = deque()  # udpin: parsed, not yet returned (msg, sender)
        raw_write = self.conn.write
        if self.spec.scheme == "udpin":
            raw_write = self._udpin_write
            self.conn.recv_msg = self._udpin_recv_msg  # type: ignore[method-assign]

        def locked_write(buf: bytes) -> None:
            with self.write_lock:
                raw_write(buf)

        self.conn.write = locked_write  # type: ignore[method-assign]
        self.mav = self.conn.mav
        self.mav.robust_parsing = True  # bad bytes become BAD_DATA instead of exceptions
        apply_key(self.mav, key)
        raw_send = self.mav.send

        def routed_send(mavmsg: Any, force_mavlink1: bool = False) -> None:
            with self.write_lock:
                self._send_to = int(getattr(mavmsg, "target_system", 0) or 0)
                try:
                    raw_send(mavmsg, force_mavlink1=force_mavlink1)
                finally:
                    self._send_to = 0

        self.mav.send = routed_send  # every *_send of the dialect goes through here
        self._last_heartbeat = 0.0
        self._boot_epoch: dict[int, float] = {}
        self._boot_ms: dict[int, int] = {}  # the latest time_boot_ms heard from each vehicle
        self._status: dict[int, int] = {}
        self.reboots: dict[int, int] = {}
        self.received = 0
        self.signed_from: set[int] = set()  # system ids whose packets arrived signed
        # The slowest COMMAND_ACK round trip seen from each vehicle (command_long): how long a command
        # that needs a quick repeat (fly's mission start) waits before taking it for lost.
        self.ack_rtt_s: dict[int, float] = {}

    # -- several vehicles on one udpin port
    def _udpin_recv_msg(self) -> Any | None:
        """pymavlink's udpin reader parses one packet per call and keeps the rest in its buffer while
        the next datagram (maybe another vehicle's) arrives; then who sent what is lost. We parse each
        datagram whole and remember its sender by the packets' source system."""
        conn = self.conn
        if not self._datagrams:
            try:
                data, sender = conn.port.recvfrom(65535)
            except OSError as err:
                if err.errno in (errno.EAGAIN, errno.EWOULDBLOCK, errno.ECONNREFUSED):
                    return None
                raise
            for msg in self.mav.parse_buffer(data) or []:
                self._datagrams.append((msg, sender))
            if not self._datagrams:
                return None
        msg, sender = self._datagrams.popleft()
        if msg.get_type() != "BAD_DATA":
            src = msg.get_srcSystem()
            if src not in (0, self.mav.srcSystem):
                self.addresses[src] = sender
            conn.clients.add(sender)  # pymavlink's own list, for anything written outside routed_send
            conn.clients_last_alive[sender] = time.time()
        return msg

    def _udpin_write(self, buf: bytes) -> None:
        """To the vehicle the packet is for; to every vehicle heard when it is for no one in particular
        (or for one we have not heard yet)."""
        where = self.addresses.get(self._send_to) if self._send_to else None
        if where is not None:
            targets = [where]
        else:
            targets = list(dict.fromkeys(self.addresses.values())) or list(self.conn.clients)
        for address in targets:
            try:
                self.conn.port.sendto(buf, address)
            except OSError:
                pass  # a vehicle that went away (ICMP unreachable): the others still get theirs

    # -- sending
    def send(self, msg: Any) -> None:
        self.mav.send(msg)

    def heartbeat(self, force: bool = False) -> None:
        """Our 1 Hz GCS heartbeat: vehicles listening with udpin learn our address from it."""
        now = time.monotonic()
        if force or now - self._last_heartbeat >= 1.0:
            self._last_heartbeat = now
            self.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def command_long(self, sysid: int, command: int, params: list[float], deadline: float,
                     other: Callable[[Any], Any] | None = None, done: Callable[[], bool] | None = None,
                     tries: int = COMMAND_TRIES, wait_s: float = COMMAND_WAIT_S) -> int | None:
        """See command_long()."""
        return command_long(self, sysid, command, params, deadline, other, done, tries, wait_s)

    # -- receiving
    def recv(self, deadline: float) -> Any | None:
        """The next good message, or None once time.monotonic() passes deadline.

        BridgeError when the transport is gone for good (TCP peer closed and reconnecting failed,
        serial device unplugged)."""
        while True:
            try:
                self.heartbeat()
                msg = self.conn.recv_msg()
            except OSError as err:  # ECONNRESET (after handle_disconnect), a serial device unplugged
                if not self._closed_by_peer:
                    what = ("the serial device went away (unplugged?)" if self.spec.scheme == "serial"
                            else "the link failed")
                    raise BridgeError(f"{self.url}: {what}: {getattr(err, 'strerror', None) or err}") from None
                msg = None
            if self._closed_by_peer:
                self._reconnect()
                continue
            if msg is not None:
                if msg.get_type() == "BAD_DATA":
                    continue
                self.received += 1
                self._track_boot(msg)
                if is_signed(msg):
                    self.signed_from.add(msg.get_srcSystem())
                return msg
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            self.conn.select(min(remaining, 0.5))

    def _track_boot(self, msg: Any) -> None:
        """A vehicle that reports MAV_STATE_BOOT again, or whose time_boot_ms starts again, has rebooted."""
        if msg.get_type() == "HEARTBEAT":
            sysid = msg.get_srcSystem()
            booting = msg.system_status == mavlink.MAV_STATE_BOOT
            if booting and self._status.get(sysid, mavlink.MAV_STATE_BOOT) != mavlink.MAV_STATE_BOOT:
                self.reboots[sysid] = self.reboots.get(sysid, 0) + 1
            self._status[sysid] = int(msg.system_status)
            return
        if msg.get_type() not in CLOCK_MESSAGES:
            return
        boot_ms = getattr(msg, "time_boot_ms", None)
        if boot_ms is None:
            return
        # When did the vehicle boot, by our clock? Latency only makes it look later, so keep the
        # earliest estimate. A new boot moves that estimate later by more than REBOOT_JUMP *and*
        # sets the vehicle's clock back; a packet read late (a busy thread, a full socket buffer)
        # only does the first, so it must not count.
        sysid = msg.get_srcSystem()
        epoch = time.monotonic() - boot_ms / 1000.0
        last = self._boot_epoch.get(sysid)
        clock_back = boot_ms < self._boot_ms.get(sysid, 0) - REBOOT_JUMP * 1000.0
        if last is not None and epoch - last > REBOOT_JUMP and clock_back:
            self.reboots[sysid] = self.reboots.get(sysid, 0) + 1
            self._boot_epoch[sysid] = epoch
            self._boot_ms[sysid] = boot_ms
        else:
            self._boot_epoch[sysid] = epoch if last is None else min(last, epoch)
            self._boot_ms[sysid] = max(self._boot_ms.get(sysid, 0), boot_ms)

    # -- a TCP peer that closed the connection
    def _peer_closed(self) -> None:
        self._closed_by_peer = True

    def _reconnect(self) -> None:
        """Reconnect to the TCP peer after it closed the connection: RECONNECT_TRIES attempts, at most
        MAX_RECONNECTS times per Link; BridgeError when that fails. Said once per event on the log."""
        self._closed_by_peer = False
        self.reconnects += 1
        where = f"{self.spec.host}:{self.spec.port}"
        if self.reconnects > MAX_RECONNECTS:
            raise BridgeError(f"{self.url}: the other end closed the TCP connection {self.reconnects} times; "
                              "giving up")
        log.warning("%s: the other end closed the TCP connection; reconnecting (up to %d tries)", self.url,
                    RECONNECT_TRIES)
        try:
            self.conn.port.close()
        except OSError:
            pass
        problem = "no answer"
        for attempt in range(RECONNECT_TRIES):
            if attempt:
                time.sleep(RECONNECT_WAIT_S)
            try:
                sock = socket.create_connection((self.spec.host, self.spec.port), timeout=RECONNECT_WAIT_S)
            except OSError as err:
                problem = err.strerror or str(err)
                continue
            sock.setblocking(False)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.conn.port = sock
            self.conn.fd = sock.fileno()
            self.mav.buf, self.mav.buf_index = bytearray(), 0  # half a packet from the old connection
            log.warning("%s: reconnected to %s", self.url, where)
            return
        raise BridgeError(f"{self.url}: the other end closed the TCP connection and {RECONNECT_TRIES} reconnects "
                          f"over {RECONNECT_TRIES * RECONNECT_WAIT_S:g} s failed ({problem})")

    @property
    def bad_signatures(self) -> int:
        """Packets refused because their signature did not match our key (or was missing)."""
        wrong, unsigned, _ = refused_packets(self.mav)
        return wrong + unsigned

    @property
    def stale_signatures(self) -> int:
        """Packets signed with our key but refused for an old timestamp (see link.signing)."""
        return refused_packets(self.mav)[2]

    def signing_problem(self) -> str:
        """Why packets were refused by our signature check, as a clause for a message ("" when none were)."""
        wrong, unsigned, stale = refused_packets(self.mav)
        if stale:
            return (f"{stale} packets carried the right signature but signing timestamps more than 60 s behind "
                    "this computer's clock, or going backwards (the key is right; the vehicle's signing clock "
                    "lags ours: check this computer's date and the vehicle's time source)")
        if wrong:
            return (f"{wrong} packets were refused because they were signed with another key "
                    "(wrong --signing-key?)")
        if unsigned:
            return (f"{unsigned} packets were refused because they were not signed: the vehicle does not sign "
                    "(put the key on it first, or leave out --signing-key)")
        return ""

    def signing_hint(self, sysid: int) -> str:
        """MAVLink 2 signing as the likely reason system sysid does not answer us, as a clause to append
        to a "did not answer" message; "" when signing does not explain it. Without a key: the
        vehicle's packets arrive signed, so it most likely requires signed packets and drops ours.
        With a key: the vehicle's packets are refused by our check (another key, none, a stale
        clock). The one place this is decided: parameters, mission transfers and commands ask here."""
        if self.key is None and sysid in self.signed_from:
            return ("the vehicle signs its MAVLink (MAVLink 2 signing) and this link sends unsigned, so it likely "
                    "ignores us; give --signing-key")
        return self.signing_problem()

    def close(self) -> None:
        try:
            self.conn.close()
        except OSError:
            pass

    def __enter__(self) -> Link:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def command_long(link: Any, sysid: int, command: int, params: list[float], deadline: float,
                 other: Callable[[Any], Any] | None = None, done: Callable[[], bool] | None = None,
                 tries: int = COMMAND_TRIES, wait_s: float = COMMAND_WAIT_S) -> int | None:
    """COMMAND_LONG over `link` (a Link, or a link.shared_link.VehicleLink) to (sysid, autopilot) with
    retries, the confirmation counting up; the MAV_RESULT of its COMMAND_ACK, or None without one. Other messages of
    that vehicle that arrive meanwhile go to `other`, when given. `done` says the command has visibly taken effect: then
    a lost acknowledgement is not worth a repeat (MAVLink repeats are executed again, and a repeated
    mission start may restart the mission on some autopilots), and the answer is ACCEPTED. An answer to
    the first send updates link.ack_rtt_s, the vehicle's slowest round trip."""
    padded = (list(params) + [0.0] * 7)[:7]
    for attempt in range(tries):
        if attempt and done is not None and done():
            return mavlink.MAV_RESULT_ACCEPTED
        link.mav.command_long_send(sysid, AUTOPILOT_COMPONENT_ID, command, attempt, *padded)
        sent_at = time.monotonic()
        wait_until = min(sent_at + wait_s, deadline)
        while (msg := link.recv(wait_until)) is not None:
            if msg.get_srcSystem() != sysid:
                continue
            if msg.get_type() == "COMMAND_ACK" and int(msg.command) == command:
                if attempt == 0:  # after a repeat, whose answer this is cannot be told
                    link.ack_rtt_s[sysid] = max(link.ack_rtt_s.get(sysid, 0.0), time.monotonic() - sent_at)
                return int(msg.result)
            if other is not None:
                other(msg)
        if time.monotonic() >= deadline:
            break
    return None


def _open_serial(spec: ConnectionSpec, url: str, source_system: int, source_component: int) -> Any:
    """A pymavlink serial connection; a device that is not there is bad input (exit 2), one that
    cannot be opened an operational failure (exit 1, with the usual causes named)."""
    if not spec.device.upper().startswith("COM") and not os.path.exists(spec.device):
        raise BridgeUsageError(Named("{connect} {0}: no such device {1} (is the radio or autopilot plugged "
                                     "in? see ls /dev/serial/by-id/)", url, spec.device))
    try:
        import serial  # noqa: F401  (pyserial: pymavlink imports it when it opens the port)
    except ImportError:
        raise BridgeError(f"cannot open {url}: serial links need pyserial (pip install pyserial==3.5)") from None
    try:
        return mavutil.mavlink_connection(spec.device, baud=spec.baud, source_system=source_system,
                                          source_component=source_component, autoreconnect=False)
    except OSError as err:  # serial.SerialException is an OSError
        detail = getattr(err, "strerror", None) or str(err)
        hint = " (add yourself to the dialout group, or check who else has the port open)" if (
            getattr(err, "errno", None) in (13, 16) or "ermission" in detail or "busy" in detail) else ""
        raise BridgeError(f"cannot open {url}: {detail}{hint}") from None


def wait_vehicle(link: Link, sysid: int, compid: int = AUTOPILOT_COMPONENT_ID, timeout: float = 10.0) -> VehicleInfo:
    """Wait for the HEARTBEAT of system sysid (component compid); BridgeError naming it on time-out."""
    deadline = time.monotonic() + timeout
    others: set[tuple[int, int]] = set()
    link.heartbeat(force=True)
    while True:
        msg = link.recv(deadline)
        if msg is None:
            break
        if msg.get_type() != "HEARTBEAT":
            continue
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if msg.type == mavlink.MAV_TYPE_GCS or msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID:
            continue  # another ground station
        if src == (sysid, compid):
            return VehicleInfo(sysid=sysid, compid=compid, autopilot=int(msg.autopilot), mav_type=int(msg.type),
                               flavour=Flavour.from_autopilot(int(msg.autopilot)), signed=is_signed(msg))
        others.add(src)
    detail = ""
    heard = getattr(link, "heard_systems", None)  # a shared link's view: what the others on it heard
    if heard is not None:
        others |= {src for src in heard() if src != (sysid, compid)}
    if others:
        detail = "; heard only " + ", ".join(f"system {s} component {c}" for s, c in sorted(others))
    elif hint := link.signing_hint(sysid):
        detail = "; " + hint
    elif link.received == 0:
        detail = "; nothing was received at all"
    raise BridgeError(f"no heartbeat from system {sysid} (component {compid}) on {link.url} within {timeout:g} s{detail}")
