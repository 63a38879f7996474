"""The mock autopilot's link: one process (or one background thread) serving one or many system ids.

Owns the transport and the faults. MockAutopilot listens on a pymavlink-style URL — `udpin:HOST:PORT`
(serves every ground station that sends to it), `udpout:HOST:PORT` (sends to a ground station
listening there) or `tcpin:HOST:PORT` (accepts TCP clients) — with port 0 meaning "pick a free one";
or on a serial line: `DEVICE,BAUD` (a real port, e.g. one end of a USB-serial null-modem pair) or
`pty` (a pseudo-terminal pair made here: the mock keeps the master, a ground station opens the
slave /dev/pts/N like a serial port; client_url names it). A serial line carries no more than the
bytes: the baud rate is set on a real port but not simulated.
Every vehicle's output goes to every peer (like a shared radio link); each vehicle only acts on
messages addressed to its system id. Faults are injected per packet and per direction: loss,
duplicates, reordering (a packet held back so later ones overtake it) and added latency; the reboot
faults live on the vehicle (MockVehicle.reboot_after_items, during an upload, and
reboot_at_item, in flight). kill(sysid) (now, or at a mission item) makes one vehicle silent for good, as
a SITL process killed in flight; when every vehicle of the mock is killed its transport closes too (its
sockets, TCP clients and serial line), as the killed process's would. set_battery(sysid, volts) is
SITL's SIM_BATT_VOLTAGE (a ground station can PARAM_SET it too), for ArduPilot's battery failsafe
(mock_vehicle); set_wind is SITL's SIM_WIND_* (flight_models.wind), set_gps_glitch its SIM_GPS1_GLTCH_X / _Y
(gps_glitch). The faults per packet are link_faults.LinkFaults. With a signing key, packets that are
unsigned or signed with another key are dropped and everything sent is signed. The server thread outlives
anything one message or one vehicle's step raises: it is logged in one escaped line (vehicle_part.log_error),
counted in the vehicle's handler_errors, a mission transfer is answered with MAV_MISSION_ERROR, and the
mock serves on.

Use it in-process (`with MockAutopilot(...) as mock:` or start()/stop(); it runs on a daemon thread)
or as the `missionplan mock` command (serve_forever()).
"""

from __future__ import annotations

import heapq
import itertools
import math
import os
import random
import select
import socket
import termios
import threading
import time
import tty
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from missionplan.base.naming import Named

from ..errors import BridgeUsageError
from ..link.connection import ConnectionSpec, mavlink, parse_url
from ..formats.mission_items import Flavour
from .gps_glitch import glitch_params
from .mock_terrain import GroundModel
from .link_faults import LinkFaults
from .mock_vehicle import MockVehicle, VehicleOptions, ground_amsl
from .vehicle_params import ARDUPILOT_MOUNT_PARAM, PX4_MOUNT_PARAM, configured_camera
from .vehicle_part import log_error
from ..link.signing import SigningKey, apply_key

TICK = 0.005  # loop period when nothing arrives: timers and flight advance at least this often
MAX_PEERS = 32


class _Writer:
    """The file object a vehicle's pymavlink encoder writes to: hands bytes to the mock's link."""

    def __init__(self, mock: MockAutopilot) -> None:
        self.mock = mock

    def write(self, buf: bytes) -> None:
        self.mock._outgoing(bytes(buf))


@dataclass
class _Peer:
    """A ground station we talk to: its address (UDP) or socket (TCP) and its signing-aware parser."""

    key: Any
    parser: Any
    sock: socket.socket | None = None  # TCP client socket
    fd: int | None = None  # serial line / pty master
    framer: Any = None  # TCP and serial: splits the stream into packets before the faults
    last_seen: float = 0.0
    alive: bool = True
    stats: dict[str, int] = field(default_factory=lambda: {"in": 0, "out": 0})


class MockAutopilot:
    """A pure-Python autopilot simulator for one or many system ids on one loopback link."""

    def __init__(self, listen: str = "udpin:127.0.0.1:0", sysids: Iterable[int] = (1,),
                 flavour: Flavour | str = Flavour.ARDUPILOT, speedup: float = 1.0, faults: LinkFaults | None = None,
                 key: SigningKey | None = None, request_interval: float | None = None,
                 upload_timeout: float | None = None, homes: dict[int, tuple[float, float, float]] | None = None,
                 cruise_speed: float = 5.0, max_items: int = 10_000,
                 clock: Callable[[], float] | None = None, gps_fix_after: float = 0.0,
                 streams_until_asked: bool = False, sitl_like: bool = False,
                 mission_check_s: float | None = None, ground: GroundModel | None = None,
                 mavlink_camera: bool = False, camera_failures: tuple[int, ...] = ()) -> None:
        """clock: the vehicles' wall clock (seconds since 1970) for signing timestamps; default time.time.
        gps_fix_after: simulated seconds until each vehicle has a GPS fix, EKF, home and lets itself be
        armed (ArduCopter SITL: 35-40); streams_until_asked: no telemetry but HEARTBEAT until
        SET_MESSAGE_INTERVAL asks for it (ArduPilot's default). Both together: a SITL-like fleet.
        sitl_like: each vehicle also behaves like ArduCopter SITL in flight (mock_vehicle's module doc):
        no camera until CAM1_TYPE is set and the vehicle rebooted (configure_camera), img_idx from 1
        across flights, ArduCopter's navigation parameters and flight. mission_check_s (PX4): simulated
        seconds after a mission upload during which MISSION_START is DENIED ("No valid mission").
        ground: the true ground of every vehicle's world (a DEM, geo.dem.Ground): its home altitude is the
        ground's at its home, it lands on the ground, and an ArduPilot vehicle asks for its terrain as ArduCopter
        SITL does with no terrain files and flies terrain-frame items from what it was sent (mock_terrain).
        BridgeUsageError when the ground has no height at a vehicle's home. mavlink_camera: each vehicle has a
        MAVLink camera (mock_camera; configure_camera sets CAM1_TYPE 6, PX4's TRIG_INTERFACE 3), whose capture
        indices camera_failures fail (capture_result 0)."""
        if str(listen).strip().lower() == "pty":
            self.spec = ConnectionSpec("pty", baud=57600)
        else:
            self.spec = parse_url(listen, "listen", allow_any_port=True)
        if self.spec.scheme not in ("udpin", "udpout", "tcpin", "serial", "pty"):
            raise BridgeUsageError(Named("{listen} {0}: the mock serves udpin:, udpout: or tcpin: URLs, a serial "
                                         "device (/dev/ttyUSB1,57600) or pty", listen))
        if speedup <= 0:
            raise BridgeUsageError(Named("{speedup} must be positive, got {0}", speedup))
        self.flavour = Flavour(flavour)
        self.faults = faults or LinkFaults()
        self.key = key
        self.clock = clock
        self._rng = random.Random(self.faults.seed)
        self._lock = threading.RLock()
        self._queue: list[tuple[float, int, str, Any, bytes]] = []  # due, order, direction, peer key, bytes
        self._order = itertools.count()
        self._peers: dict[Any, _Peer] = {}
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._sock: socket.socket | None = None
        self._listener: socket.socket | None = None
        self._pty_slave: int | None = None  # held open so the master never reads EIO between clients
        self.device = ""
        self._greet = False
        self._transport_closed = False  # every vehicle killed: nothing left to serve
        self.stats = {"in": 0, "out": 0, "dropped_in": 0, "dropped_out": 0, "rejected": 0, "clients": 0}
        now = time.monotonic()
        self.vehicles: dict[int, MockVehicle] = {}
        base_home = (45.0703, 7.6869, 240.0)
        for index, sysid in enumerate(sysids):
            home = (homes or {}).get(sysid, (base_home[0] + 0.0005 * index, base_home[1], base_home[2]))
            if ground is not None and not math.isfinite(ground_amsl(ground, home[0], home[1])):
                raise BridgeUsageError(f"the ground has no height at vehicle {sysid}'s home {home[0]:.7f}, "
                                       f"{home[1]:.7f}")
            options = VehicleOptions(flavour=self.flavour, home=home, request_interval=request_interval,
                                     upload_timeout=upload_timeout, speedup=speedup, cruise_speed=cruise_speed,
                                     max_items=max_items, gps_fix_after=gps_fix_after,
                                     streams_until_asked=streams_until_asked, sitl_like=sitl_like,
                                     mission_check_s=mission_check_s, ground=ground,
                                     mavlink_camera=mavlink_camera, camera_failures=tuple(camera_failures))
            encoder = mavlink.MAVLink(_Writer(self), srcSystem=sysid, srcComponent=mavlink.MAV_COMP_ID_AUTOPILOT1)
            apply_key(encoder, key, link_id=index, clock=clock)
            self.vehicles[sysid] = MockVehicle(sysid, options, encoder, now)
        if not self.vehicles:
            raise BridgeUsageError("the mock needs at least one system id")
        self._open()

    # ------------------------------------------------------------------------------ transport
    def _open(self) -> None:
        spec = self.spec
        try:
            if spec.scheme in ("serial", "pty"):
                self._open_serial()
            elif spec.scheme == "tcpin":
                self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                self._listener.bind((spec.host, spec.port))
                self._listener.listen(8)
                self._listener.setblocking(False)
                self.address = self._listener.getsockname()[:2]
            else:
                self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                if spec.scheme == "udpin":
                    self._sock.bind((spec.host, spec.port))
                else:
                    self._sock.bind((spec.host, 0))
                    self._peer(("udp", (socket.gethostbyname(spec.host), spec.port)), time.monotonic())
                self._sock.setblocking(False)
                self.address = self._sock.getsockname()[:2]
        except OSError as err:
            self.close_sockets()
            raise BridgeUsageError(Named("{listen} {0}: cannot open ({1})", spec.url if spec.scheme != "pty" else "pty",
                                         err.strerror)) from None

    def _open_serial(self) -> None:
        """A serial device (raw, at its baud) or a fresh pty pair; one peer: the other end of the line."""
        if self.spec.scheme == "pty":
            master, slave = os.openpty()
            tty.setraw(slave)  # no echo, no line editing: bytes pass as they are, both ways
            self._pty_slave = slave
            self.device = os.ttyname(slave)
            fd = master
        else:
            self.device = self.spec.device
            fd = os.open(self.device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            try:
                tty.setraw(fd)
                speed = getattr(termios, f"B{self.spec.baud}", None)
                if speed is not None:
                    attrs = termios.tcgetattr(fd)
                    attrs[4] = attrs[5] = speed
                    termios.tcsetattr(fd, termios.TCSANOW, attrs)
            except termios.error:
                os.close(fd)
                raise BridgeUsageError(Named("{listen} {0}: {1} is not a serial device", self.spec.url,
                                             self.device)) from None
        os.set_blocking(fd, False)
        self.address = (self.device, 0)
        self._peer(("serial", self.device), time.monotonic(), fd=fd)

    @property
    def port(self) -> int:
        return int(self.address[1])

    @property
    def client_url(self) -> str:
        """The pymavlink URL a ground station uses to reach this mock (serial: this end's device)."""
        host = self.address[0]
        if self.spec.scheme in ("serial", "pty"):
            return f"{self.device},{self.spec.baud}"
        if self.spec.scheme == "tcpin":
            return f"tcp:{host}:{self.port}"
        if self.spec.scheme == "udpin":
            return f"udpout:{host}:{self.port}"
        return f"udpin:{self.spec.host}:{self.spec.port}"

    @property
    def mavsdk_url(self) -> str:
        """The same for MAVSDK's URL syntax."""
        host = self.address[0]
        if self.spec.scheme in ("serial", "pty"):
            return f"serial://{self.device}:{self.spec.baud}"
        if self.spec.scheme == "tcpin":
            return f"tcpout://{host}:{self.port}"
        if self.spec.scheme == "udpin":
            return f"udpout://{host}:{self.port}"
        return f"udpin://{self.spec.host}:{self.spec.port}"

    def _new_parser(self) -> Any:
        parser = mavlink.MAVLink(None, srcSystem=0, srcComponent=0)
        parser.robust_parsing = True
        apply_key(parser, self.key, clock=self.clock)
        return parser

    def _peer(self, key: Any, now: float, sock: socket.socket | None = None, fd: int | None = None) -> _Peer:
        peer = self._peers.get(key)
        if peer is None:
            if len(self._peers) >= MAX_PEERS:  # forget the quietest UDP peer
                oldest = min((p for p in self._peers.values() if p.sock is None), key=lambda p: p.last_seen,
                             default=None)
                if oldest is not None:
                    del self._peers[oldest.key]
            framer = None
            if sock is not None or fd is not None:
                framer = mavlink.MAVLink(None)
                framer.robust_parsing = True
            peer = _Peer(key=key, parser=self._new_parser(), sock=sock, fd=fd, framer=framer)
            self._peers[key] = peer
            self._greet = True
        peer.last_seen = now
        return peer

    def _outgoing(self, buf: bytes) -> None:
        """A vehicle sent a packet: through the outbound faults to every peer."""
        now = time.monotonic()
        for peer in list(self._peers.values()):
            self._through_faults("out", peer.key, buf, now)

    def _through_faults(self, direction: str, peer_key: Any, buf: bytes, now: float) -> None:
        f = self.faults
        loss = f.loss_in if direction == "in" else f.loss_out
        rng = self._rng
        if loss and rng.random() < loss:
            self.stats["dropped_" + direction] += 1
            return
        copies = 2 if f.duplicate and rng.random() < f.duplicate else 1
        for _ in range(copies):
            delay = f.latency
            if f.reorder and rng.random() < f.reorder:
                delay += f.reorder_delay * (0.5 + rng.random())
            if delay <= 0:
                self._deliver(direction, peer_key, buf, now)
            else:
                heapq.heappush(self._queue, (now + delay, next(self._order), direction, peer_key, buf))

    def _deliver(self, direction: str, peer_key: Any, buf: bytes, now: float) -> None:
        peer = self._peers.get(peer_key)
        if peer is None or not peer.alive:
            return
        if direction == "out":
            self.stats["out"] += 1
            try:
                if peer.fd is not None:
                    os.write(peer.fd, buf)  # a full line buffer drops the packet, as a radio would
                elif peer.sock is not None:
                    peer.sock.sendall(buf)
                elif self._sock is not None:
                    self._sock.sendto(buf, peer_key[1])
            except OSError:
                if peer.sock is not None:
                    self._drop_peer(peer)
            return
        self.stats["in"] += 1
        before = peer.parser.signing.badsig_count + peer.parser.signing.reject_count
        messages = peer.parser.parse_buffer(buf) or []
        if peer.parser.signing.badsig_count + peer.parser.signing.reject_count > before:
            self.stats["rejected"] += 1
        for msg in messages:
            if msg.get_type() == "BAD_DATA":
                continue
            for vehicle in self.vehicles.values():
                try:
                    vehicle.handle(msg, now)  # its parts answer their own failures (vehicle_part)
                except Exception as err:  # noqa: BLE001 (the server thread must outlive any one message)
                    self._survived(vehicle, f"{type(err).__name__} taking {msg.get_type()}: {err}")

    def _survived(self, vehicle: MockVehicle, what: str) -> None:
        """Something unexpected raised in the server thread: logged in one line, counted, and served on."""
        vehicle.handler_errors += 1
        log_error(f"mock vehicle {vehicle.sysid}: {what}")

    def _drop_peer(self, peer: _Peer) -> None:
        peer.alive = False
        self._peers.pop(peer.key, None)
        try:
            if peer.sock is not None:
                peer.sock.close()
            if peer.fd is not None:
                os.close(peer.fd)
        except OSError:
            pass

    def _read(self, readable: list[Any], now: float) -> None:
        if self._listener is not None and self._listener in readable:
            try:
                client, addr = self._listener.accept()
                self.stats["clients"] += 1
                client.setblocking(False)
                client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self._peer(("tcp", addr), now, sock=client)
            except OSError:
                pass
        if self._sock is not None and self._sock in readable:
            for _ in range(256):  # drain what is there, but let timers run
                try:
                    data, addr = self._sock.recvfrom(65535)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:
                    break  # e.g. ICMP port unreachable from a peer that went away
                if self.spec.scheme == "udpout":
                    key = next(iter(self._peers))  # our one destination; replies come from it
                else:
                    key = ("udp", addr)
                self._peer(key, now)
                self._through_faults("in", key, data, now)
        for peer in list(self._peers.values()):
            if peer.fd is not None and peer.fd in readable:
                try:
                    data = os.read(peer.fd, 65536)
                except OSError:  # EAGAIN, or EIO from a line with nobody on it: nothing to read
                    continue
            elif peer.sock is not None and peer.sock in readable:
                try:
                    data = peer.sock.recv(65536)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    data = b""
                if not data:
                    self._drop_peer(peer)
                    continue
            else:
                continue
            peer.last_seen = now
            for msg in peer.framer.parse_buffer(data) or []:
                if msg.get_type() != "BAD_DATA":
                    self._through_faults("in", peer.key, bytes(msg.get_msgbuf()), now)

    # ------------------------------------------------------------------------------ the loop
    def _loop_once(self) -> None:
        now = time.monotonic()
        timeout = TICK
        if self._queue:
            timeout = min(timeout, max(self._queue[0][0] - now, 0.0))
        sockets: list[Any] = [s for s in (self._sock, self._listener) if s is not None]
        sockets += [p.sock for p in self._peers.values() if p.sock is not None]
        sockets += [p.fd for p in self._peers.values() if p.fd is not None]
        try:
            readable, _, _ = select.select(sockets, [], [], timeout)
        except (OSError, ValueError):
            readable = []
        if self._transport_closed:  # every vehicle killed: a dead process serves nothing
            self._stop.wait(TICK)
            return
        with self._lock:
            now = time.monotonic()
            self._read(readable, now)
            if self._greet:  # a new ground station: let it hear every vehicle now, not in up to 1 s
                self._greet = False
                for vehicle in self.vehicles.values():
                    if vehicle.online:
                        vehicle.send_heartbeat()
            while self._queue and self._queue[0][0] <= now:
                _, _, direction, peer_key, buf = heapq.heappop(self._queue)
                self._deliver(direction, peer_key, buf, now)
            for vehicle in self.vehicles.values():
                try:
                    vehicle.tick(now)
                except Exception as err:  # noqa: BLE001 (the server thread must outlive any one vehicle's step)
                    self._survived(vehicle, f"{type(err).__name__} in its step: {err}")
            if not self._transport_closed and all(v.killed for v in self.vehicles.values()):
                self._close_if_all_killed()

    def _run(self) -> None:
        while not self._stop.is_set():
            self._loop_once()

    def start(self) -> MockAutopilot:
        """Serve on a daemon thread until stop()."""
        if self._thread is None:
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name=f"mock-autopilot-{self.port}", daemon=True)
            self._thread.start()
        return self

    @property
    def serving(self) -> bool:
        """Whether start()'s server thread is alive: a vehicle's handler that raised must not end it."""
        return self._thread is not None and self._thread.is_alive()

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        self.close_sockets()

    def serve_forever(self) -> None:
        """Serve on the calling thread until stop() or KeyboardInterrupt."""
        try:
            self._run()
        finally:
            self.close_sockets()

    def close_sockets(self) -> None:
        for peer in list(self._peers.values()):
            if peer.sock is not None or peer.fd is not None:
                self._drop_peer(peer)
        if self._pty_slave is not None:
            try:
                os.close(self._pty_slave)
            except OSError:
                pass
            self._pty_slave = None
        for sock in (self._sock, self._listener):
            if sock is not None:
                try:
                    sock.close()
                except OSError:
                    pass
        self._sock = self._listener = None

    def __enter__(self) -> MockAutopilot:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ------------------------------------------------------------------------------ test helpers
    def vehicle(self, sysid: int) -> MockVehicle:
        return self.vehicles[sysid]

    def mission(self, sysid: int, mission_type: int = 0) -> list[Any]:
        """A copy of what vehicle sysid holds (thread-safe)."""
        with self._lock:
            return self.vehicles[sysid].mission(mission_type)

    def drop_clients(self) -> None:
        """Close every TCP client's connection (the listener stays): a link that breaks mid-transfer."""
        with self._lock:
            for peer in list(self._peers.values()):
                if peer.sock is not None:
                    self._drop_peer(peer)

    def set_faults(self, faults: LinkFaults) -> None:
        with self._lock:
            self.faults = faults
            self._rng = random.Random(faults.seed)

    def reboot_after_items(self, sysid: int, items: int, offline: float = 0.3) -> None:
        """Vehicle sysid reboots once, when the next upload has delivered `items` items."""
        with self._lock:
            vehicle = self.vehicles[sysid]
            vehicle.reboot_after_items = items
            vehicle.reboot_offline = offline

    def kill(self, sysid: int, at_item: int | None = None) -> None:
        """Vehicle sysid goes silent for good, as a SITL process killed (SIGKILL) in flight: now, or once it
        has reached mission item `at_item`. It sends nothing more (no HEARTBEAT either), hears nothing, and
        its state stays as it was (mock.vehicle(sysid).flight.state: where it was killed). When every
        vehicle is killed, the mock's transport closes as the process's would (stop() still ends the thread)."""
        with self._lock:
            vehicle = self.vehicles[sysid]
            if at_item is not None:
                vehicle.kill_at_item = at_item
                return
            vehicle.kill()
            self._close_if_all_killed()

    def killed(self, sysid: int) -> bool:
        return self.vehicles[sysid].killed

    @property
    def transport_closed(self) -> bool:
        """Every vehicle was killed: the sockets (listener, clients, serial line) are closed."""
        return self._transport_closed

    def _close_if_all_killed(self) -> None:
        if self.vehicles and all(v.killed for v in self.vehicles.values()) and not self._transport_closed:
            self._transport_closed = True
            self._queue.clear()
            self.close_sockets()

    def set_battery(self, sysid: int, volts: float) -> None:
        """The battery voltage vehicle sysid reads (ArduPilot flavour: SITL's SIM_BATT_VOLTAGE parameter;
        below BATT_LOW_VOLT for BATT_LOW_TIMER simulated seconds while armed, its battery failsafe acts)."""
        with self._lock:
            vehicle = self.vehicles[sysid]
            if "SIM_BATT_VOLTAGE" not in vehicle.params:
                raise BridgeUsageError(f"vehicle {sysid} ({vehicle.flavour.value}) has no simulated battery")
            vehicle.params["SIM_BATT_VOLTAGE"] = float(volts)

    def set_wind(self, speed_mps: float, from_deg: float, turbulence_mps: float = 0.0, sysid: int | None = None,
                 seed: int | None = None) -> None:
        """SITL's SIM_WIND_SPD, _DIR (where the wind comes FROM, degrees) and _TURB on vehicle sysid (None: every
        vehicle), as a PARAM_SET of them would; seed: its gusts' random seed (default: its system id)."""
        with self._lock:
            for vehicle in self.vehicles.values() if sysid is None else [self.vehicles[sysid]]:
                vehicle.set_wind(speed_mps, from_deg, turbulence_mps, seed)

    def set_gps_glitch(self, sysid: int, north_m: float, east_m: float) -> None:
        """SITL's SIM_GPS1_GLTCH_X / _Y (degrees) for a GPS offset in metres on vehicle sysid; 0, 0 clears it."""
        with self._lock:
            self.vehicles[sysid].params.update(glitch_params(north_m, east_m, self.vehicles[sysid].options.home[0]))

    def reboot_in_flight(self, sysid: int, after_item: int, offline: float = 0.3) -> None:
        """Vehicle sysid reboots once, in flight, when it has reached mission item `after_item`."""
        with self._lock:
            vehicle = self.vehicles[sysid]
            vehicle.reboot_at_item = after_item
            vehicle.reboot_offline = offline

    def configure_camera(self, sysid: int, offline: float = 0.05) -> None:
        """What a team does once on a real vehicle: CAM1_TYPE = 1 (PX4: TRIG_MODE = 4, distance-triggered
        by the mission), 6 with a MAVLink camera (PX4: TRIG_INTERFACE 3), the camera on a mount that reports where
        it points (MNT1_TYPE = 1, a servo mount; PX4: MNT_MODE_IN = 0, its gimbal module) and a reboot (they take
        effect at boot)."""
        with self._lock:
            vehicle = self.vehicles[sysid]
            mavlink_camera = vehicle.mavlink_camera is not None  # TRIG_INTERFACE 3 / CAM1_TYPE 6: a MAVLink camera
            vehicle.params.update(configured_camera(vehicle.flavour, mavlink_camera))
            vehicle.params[PX4_MOUNT_PARAM if vehicle.flavour is Flavour.PX4 else ARDUPILOT_MOUNT_PARAM] = (
                0.0 if vehicle.flavour is Flavour.PX4 else 1.0)
            vehicle.reboot(time.monotonic(), offline)

    def configure_cameras(self) -> MockAutopilot:
        """configure_camera on every vehicle: a fleet as a team has set it up before its first survey."""
        for sysid in list(self.vehicles):
            self.configure_camera(sysid)
        return self

    def wait_until(self, predicate: Any, timeout: float) -> bool:
        """Poll predicate(self) under the lock until true or timeout; returns the last value."""
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:
                if predicate(self):
                    return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
