"""The second backend: MAVSDK-Python 4.x (ctypes binding of the C++ library; no server process).

Owns mission upload / download / clear / set-current through MAVSDK's MissionRaw plugin for one
vehicle picked by system id. MAVSDK runs the mission protocol (its own retries and time-outs);
the bytes travel over our pymavlink Link through a `raw://` connection: a pump thread passes every
authentic packet from the link to MAVSDK, and MAVSDK's packets go out on the link (re-signed when a
signing key is set, since MAVSDK-Python 4.1 has no signing API of its own). That gives the mavsdk
backend the same connection strings and the same signing as the pymavlink one.

Read-back: MAVSDK's own download first. MAVSDK gives an item up after 5 tries (hard-coded), so on a
very lossy link (20 % each way) a long download can fail there; the read-back is then repeated with
our pymavlink downloader over the same link, and the report says which one verified.
"""

from __future__ import annotations

import ctypes
import logging
import threading
import time
from typing import Any

from ..errors import BridgeError
from ..link.connection import AUTOPILOT_COMPONENT_ID, Link, VehicleInfo, mavlink, wait_vehicle
from ..formats.mission_items import MissionType, WireItem
from ..link.params import ParamClient, set_param
from .protocol import MissionClient, MissionTransferError, ProgressFn, Timeouts
from ..link.signing import SigningKey, apply_key

log = logging.getLogger(__name__)

MAVSDK_SYSTEM_ID = 245  # MAVSDK's default ground-station identity
MAVSDK_COMPONENT_ID = mavlink.MAV_COMP_ID_MISSIONPLANNER


def _import_mavsdk() -> Any:
    try:
        import mavsdk
        from mavsdk.plugins import mission_raw
    except ImportError as err:  # pragma: no cover - mavsdk is a project dependency
        raise BridgeError(f"--backend mavsdk needs the mavsdk package (pip install mavsdk): {err}") from None
    return mavsdk, mission_raw


_NATIVE_LOCK = threading.Lock()  # creating and destroying MAVSDK instances: one thread at a time
_logs_routed = False


def _route_mavsdk_logs() -> None:
    """Send MAVSDK's own log lines to Python logging instead of the terminal (once per process)."""
    global _logs_routed
    if _logs_routed:
        return
    _logs_routed = True
    mavsdk, _ = _import_mavsdk()
    levels = {0: logging.DEBUG, 1: logging.INFO, 2: logging.WARNING, 3: logging.ERROR}

    def handler(level: Any, message: str, file: str | None, line: int) -> bool:
        log.log(levels.get(int(level), logging.INFO), "%s", message)
        return True  # suppress MAVSDK's default printing

    mavsdk.log_subscribe(handler)


class MavsdkBackend:
    """MissionRaw over a raw:// connection pumped through a pymavlink Link."""

    name = "mavsdk"

    def __init__(self, url: str, sysid: int, compid: int = AUTOPILOT_COMPONENT_ID, key: SigningKey | None = None,
                 timeouts: Timeouts | None = None, connect_timeout: float = 10.0, attempts: int = 6) -> None:
        mavsdk, mission_raw = _import_mavsdk()
        self._mr = mission_raw
        self.timeouts = timeouts or Timeouts()
        self.attempts = attempts
        self.read_back_by = "mavsdk"
        self.link = Link(url, key)
        self._write_lock = threading.Lock()
        self._pump_stop = threading.Event()
        self._pump: threading.Thread | None = None
        self._mavsdk: Any = None
        self.dropped_stale = 0
        try:
            self.vehicle: VehicleInfo = wait_vehicle(self.link, sysid, compid, connect_timeout)
            self._start_mavsdk(mavsdk, connect_timeout)
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------------------ plumbing
    def _start_mavsdk(self, mavsdk: Any, connect_timeout: float) -> None:
        with _NATIVE_LOCK:  # two Mavsdk instances created at once from two threads crash the library
            _route_mavsdk_logs()
            config = mavsdk.Configuration.create_with_component_type(mavsdk.ComponentType.GROUND_STATION)
            self._mavsdk = mavsdk.Mavsdk(config)
        lib = self._mavsdk._lib
        lib.mavsdk_set_timeout_s.argtypes = [ctypes.c_void_p, ctypes.c_double]
        lib.mavsdk_set_timeout_s.restype = None
        # MAVSDK's per-step time-out: ours, so both backends wait alike.
        lib.mavsdk_set_timeout_s(self._mavsdk._handle, float(self.timeouts.item_timeout))
        # MAVSDK's packets are re-packed (and signed) by this encoder; their ids are kept.
        self._encoder = mavlink.MAVLink(self.link.conn, srcSystem=MAVSDK_SYSTEM_ID, srcComponent=MAVSDK_COMPONENT_ID)
        apply_key(self._encoder, self.link.key, link_id=1)
        self._framer = mavlink.MAVLink(None)
        self._framer.robust_parsing = True
        result = self._mavsdk.add_any_connection("raw://")
        if int(result) != 0:
            raise BridgeError(f"MAVSDK could not open its raw connection: {getattr(result, 'name', result)}")
        self._mavsdk.subscribe_raw_bytes_to_be_sent(self._from_mavsdk)
        self._resume_pump()
        self.system = self._find_system(connect_timeout)
        self.plugin = self._mr.MissionRaw(self.system)

    def _from_mavsdk(self, data: bytes) -> None:
        """MAVSDK wants to send: frame its bytes into packets and send them on our link."""
        with self._write_lock:  # MAVSDK calls from its own thread; one framer, one encoder
            for msg in self._framer.parse_buffer(data) or []:
                if msg.get_type() == "BAD_DATA":
                    continue
                if self.link.key is None:
                    self.link.conn.write(bytes(msg.get_msgbuf()))
                else:
                    self._encoder.srcSystem, self._encoder.srcComponent = msg.get_srcSystem(), msg.get_srcComponent()
                    self._encoder.send(msg)

    def _pump_loop(self) -> None:
        last_seq: dict[tuple[int, int], int] = {}
        while not self._pump_stop.is_set():
            msg = self.link.recv(time.monotonic() + 0.05)
            if msg is None or self._mavsdk is None:
                continue
            # Link-level clean-up by MAVLink packet sequence number: a duplicate or a packet that
            # arrives after a newer one is dropped. MAVSDK's mission client takes a late repeated
            # request as a rewind and then ignores the vehicle's next request until it gives up.
            stream = (msg.get_srcSystem(), msg.get_srcComponent())
            seq = msg.get_seq()
            previous = last_seq.get(stream)
            if previous is not None and (seq - previous) % 256 in (0,) + tuple(range(129, 256)):
                self.dropped_stale += 1
                continue
            last_seq[stream] = seq
            self._mavsdk.pass_received_raw_bytes(bytes(msg.get_msgbuf()))

    def _resume_pump(self) -> None:
        if self._pump is None:
            self._pump_stop.clear()
            self._pump = threading.Thread(target=self._pump_loop, name="mavsdk-pump", daemon=True)
            self._pump.start()

    def _pause_pump(self) -> None:
        if self._pump is not None:
            self._pump_stop.set()
            self._pump.join(2.0)
            self._pump = None

    def _find_system(self, timeout: float) -> Any:
        """MAVSDK's System for our sysid, once MAVSDK knows its autopilot type (it shapes the protocol)."""
        deadline = time.monotonic() + max(timeout, 3.0)
        wanted = {"ardupilot": 2, "px4": 1}.get(self.vehicle.flavour.value)
        found = None
        while time.monotonic() < deadline:
            if found is None:
                for system in self._mavsdk.get_systems():
                    if system.get_system_id() == self.vehicle.sysid and system.has_autopilot():
                        found = system
                        break
            if found is not None:
                # Before MAVSDK has seen the autopilot type it refuses ArduPilot's legacy MISSION_REQUEST.
                if wanted is None or int(found.autopilot_type()) == wanted:
                    return found
            time.sleep(0.02)
        if found is not None:
            return found
        raise BridgeError(f"MAVSDK did not discover vehicle {self.vehicle.sysid} within {max(timeout, 3.0):g} s")

    # ------------------------------------------------------------------------------ operations
    def _items(self, mission_type: int, items: list[WireItem]) -> list[Any]:
        cls = self._mr.MissionItem
        return [cls(seq=it.seq, frame=it.frame, command=it.command, current=it.current,
                    autocontinue=it.autocontinue, param1=it.param1, param2=it.param2, param3=it.param3,
                    param4=it.param4, x=it.x, y=it.y, z=it.z, mission_type=int(mission_type)) for it in items]

    def _fail(self, what: str, result: Any) -> BridgeError:
        name = getattr(result, "name", str(result))
        hint = ""
        if name == "TIMEOUT" and self.vehicle.signed and self.link.key is None:
            hint = " (the vehicle signs its packets: pass --signing-key)"
        return MissionTransferError(f"vehicle {self.vehicle.sysid}: MAVSDK {what} failed: {name}{hint}")

    def _wait(self, start: Any, what: str, total: int, progress: ProgressFn | None) -> None:
        """Run one async MissionRaw call; progress callbacks update `progress`."""
        done = threading.Event()
        outcome: dict[str, Any] = {}

        def callback(result: Any, *rest: Any) -> None:
            data = rest[0] if len(rest) > 1 else None
            if int(result) == self._mr.MissionRawResult.NEXT:
                if progress is not None and data is not None and total:
                    progress(min(int(data.progress * total), total), total)
                return
            outcome["result"] = result
            done.set()

        start(callback)
        limit = self.timeouts.step_limit * max(total, 1) + 30.0
        if not done.wait(limit):
            raise MissionTransferError(f"vehicle {self.vehicle.sysid}: MAVSDK {what} did not finish within {limit:g} s")
        if outcome["result"] != self._mr.MissionRawResult.SUCCESS:
            raise self._fail(what, outcome["result"])

    def upload(self, mission_type: int, items: list[WireItem], progress: ProgressFn | None = None) -> None:
        mission_type = int(mission_type)
        if not items:
            self.clear(mission_type)  # MAVSDK rejects an empty upload
            return
        plan_items = self._items(mission_type, items)
        last: BridgeError | None = None
        for _attempt in range(self.attempts):
            try:
                if mission_type == MissionType.MISSION:
                    plan = self._mr.MissionPlan(plan_items)
                    self._wait(lambda cb: self.plugin.upload_mission_with_progress_async(plan, cb), "mission upload",
                               len(items), progress)
                else:
                    method = (self.plugin.upload_geofence_async if mission_type == MissionType.FENCE
                              else self.plugin.upload_rally_points_async)
                    self._wait(lambda cb: method(plan_items, cb), f"{MissionType(mission_type).label} upload",
                               len(items), None)
                return
            except MissionTransferError as err:
                last = err
                if "TIMEOUT" not in str(err):
                    raise  # the vehicle said no: trying again changes nothing
                log.info("MAVSDK upload attempt failed (%s); starting it again", err)
        assert last is not None
        raise last

    def download(self, mission_type: int, progress: ProgressFn | None = None) -> list[WireItem]:
        mission_type = int(mission_type)
        method = {MissionType.MISSION: self.plugin.download_mission,
                  MissionType.FENCE: self.plugin.download_geofence,
                  MissionType.RALLY: self.plugin.download_rallypoints}[MissionType(mission_type)]
        try:
            raw = method()
            self.read_back_by = "mavsdk"
        except self._mr.MissionRawError as err:
            name = err.result.name
            if name == "NO_MISSION_AVAILABLE":
                return []
            if name != "TIMEOUT":
                raise self._fail(f"{MissionType(mission_type).label} download", err.result) from None
            # MAVSDK gave an item up after its 5 tries; read back with our downloader on the same link.
            log.info("MAVSDK download timed out; reading back with pymavlink instead")
            self._pause_pump()
            try:
                client = MissionClient(self.link, self.vehicle, self.timeouts)
                items = client.download(mission_type, progress)
            finally:
                self._resume_pump()
            self.read_back_by = "pymavlink after MAVSDK's download timed out"
            return items
        items = [WireItem(seq=it.seq, frame=it.frame, command=it.command, current=it.current,
                          autocontinue=it.autocontinue, param1=it.param1, param2=it.param2, param3=it.param3,
                          param4=it.param4, x=it.x, y=it.y, z=it.z, mission_type=it.mission_type) for it in raw]
        if progress is not None:
            progress(len(items), len(items))
        return items

    def upload_qgc_plan(self, path: str, progress: ProgressFn | None = None) -> int:
        """Let MAVSDK itself read a QGroundControl .plan (its own importer, not ours) and upload the
        mission items it found; returns how many it uploaded."""
        try:
            imported = self.plugin.import_qgroundcontrol_mission(str(path))
        except self._mr.MissionRawError as err:
            raise self._fail(f"import of {path}", err.result) from None
        items = list(imported.mission_items)
        if not items:
            raise BridgeError(f"{path}: MAVSDK's importer found no mission items")
        plan = self._mr.MissionPlan(items)
        for attempt in range(self.attempts):
            try:
                self._wait(lambda cb: self.plugin.upload_mission_with_progress_async(plan, cb),
                           "mission upload", len(items), progress)
                return len(items)
            except MissionTransferError as err:
                if "TIMEOUT" not in str(err) or attempt == self.attempts - 1:
                    raise
                log.info("MAVSDK upload attempt failed (%s); starting it again", err)
        return len(items)

    def clear(self, mission_type: int = MissionType.MISSION) -> None:
        if int(mission_type) != MissionType.MISSION:
            # MissionRaw clears only the mission; fence and rally go through our client.
            self._pause_pump()
            try:
                MissionClient(self.link, self.vehicle, self.timeouts).clear(mission_type)
            finally:
                self._resume_pump()
            return
        try:
            self.plugin.clear_mission()
        except self._mr.MissionRawError as err:
            raise self._fail("clear", err.result) from None

    def set_param(self, name: str, value: float) -> tuple[float | None, float]:
        """Through our own parameter client on the same link (MAVSDK's pump paused meanwhile)."""
        self._pause_pump()
        try:
            return set_param(ParamClient(self.link, self.vehicle), name, value)
        finally:
            self._resume_pump()

    def set_current(self, seq: int) -> None:
        try:
            self.plugin.set_current_mission_item(seq)
        except self._mr.MissionRawError as err:
            raise self._fail("set-current", err.result) from None

    def close(self) -> None:
        self._pause_pump()
        if self._mavsdk is not None:
            with _NATIVE_LOCK:
                self._mavsdk.destroy()
            self._mavsdk = None
        self.link.close()

    def __enter__(self) -> MavsdkBackend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
