"""Backend-neutral mission upload with read-back verification, and the pymavlink backend.

Owns:
- MissionBackend: what a backend offers (upload / download / clear / set-current of wire items for
  one vehicle), with two implementations: PymavlinkBackend here and MavsdkBackend in mavsdk_backend;
- open_backend: connect by URL as ground station (--gcs-sysid, --gcs-compid), find the vehicle by
  system id, learn its flavour;
- read_back_differences: download a list and compare it with what was sent;
- upload_plan: turn the mission, fence and rally lists into the vehicle's wire items by flavour,
  upload each (clear the fence / rally when the file has none), read each back and compare item by
  item by the flavour's rule (ArduPilot's item 0 is its home and is skipped). It succeeds only when
  the vehicle holds exactly what was sent. It also sets the parameters the vehicle needs to fly the
  plan as written (link.params: WPNAV_RADIUS on ArduCopter; over the ground, the terrain parameters and
  RTL_ALT_TYPE), unless told not to. A PX4 vehicle is
  first asked for its home: a plan PX4 would refuse to start from there, or fly without its
  geofence (formats.px4_rules), is not uploaded.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from missionplan.base.naming import Named

from ..errors import BridgeError, BridgeUsageError
from ..link.connection import (AUTOPILOT_COMPONENT_ID, GCS_COMPONENT_ID, GCS_SYSTEM_ID, Link, VehicleInfo, mavlink,
                               wait_vehicle)
from ..formats.mission_items import Flavour, Mission, MissionType, WireItem, from_wire, to_wire
from ..formats.readback import compare_wire
from ..link.params import (RTL_ALT_TYPE, ParamClient, ParamSetting, acceptance_radius_setting, set_param,
                           terrain_plan_settings)
from ..formats.px4_rules import MIS_DIST_1WP_DEFAULT, START_DENIED, fence_problems, start_refusals
from .protocol import MissionClient, MissionTransferError, ProgressFn, Timeouts, UploadUnconfirmed
from ..link.signing import SigningKey

PLAN_TYPES = (MissionType.MISSION, MissionType.FENCE, MissionType.RALLY)

BACKENDS = ("pymavlink", "mavsdk")


class MissionBackend(Protocol):
    """One vehicle reached through one link."""

    name: str
    vehicle: VehicleInfo

    def upload(self, mission_type: int, items: list[WireItem], progress: ProgressFn | None = None) -> None: ...

    def download(self, mission_type: int, progress: ProgressFn | None = None) -> list[WireItem]: ...

    def clear(self, mission_type: int = MissionType.MISSION) -> None: ...

    def set_current(self, seq: int) -> None: ...

    def set_param(self, name: str, value: float) -> tuple[float | None, float]: ...

    def close(self) -> None: ...


class PymavlinkBackend:
    """The default backend: our own mission protocol (transfer.protocol) over a pymavlink link."""

    name = "pymavlink"

    def __init__(self, url: str, sysid: int, compid: int = AUTOPILOT_COMPONENT_ID, key: SigningKey | None = None,
                 timeouts: Timeouts | None = None, connect_timeout: float = 10.0, link: Any = None,
                 source_system: int = GCS_SYSTEM_ID, source_component: int = GCS_COMPONENT_ID) -> None:
        """link: an open link to use instead of opening url (a link.shared_link.VehicleLink of a
        fleet's shared connection, which has its own key and identity); close() then closes only the
        view. source_system, source_component: our ground-station identity on a link we open."""
        self.link = link if link is not None else Link(url, key, source_system, source_component)
        try:
            self.vehicle = wait_vehicle(self.link, sysid, compid, connect_timeout)
        except BaseException:
            self.link.close()
            raise
        self.client = MissionClient(self.link, self.vehicle, timeouts)
        self.read_back_by = self.name

    def upload(self, mission_type: int, items: list[WireItem], progress: ProgressFn | None = None) -> None:
        self.client.upload(mission_type, items, progress)

    def download(self, mission_type: int, progress: ProgressFn | None = None) -> list[WireItem]:
        return self.client.download(mission_type, progress)

    def clear(self, mission_type: int = MissionType.MISSION) -> None:
        self.client.clear(mission_type)

    def set_current(self, seq: int) -> None:
        self.client.set_current(seq)

    def set_param(self, name: str, value: float) -> tuple[float | None, float]:
        return set_param(ParamClient(self.link, self.vehicle), name, value)

    def close(self) -> None:
        self.link.close()

    def __enter__(self) -> PymavlinkBackend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def check_gcs_identity(backend: str, source_system: int, source_component: int, setting: str = "backend") -> None:
    """MAVSDK speaks as its own ground station (system 245, component 190: transfer.mavsdk_backend) and
    takes no other identity: asking for one with it is bad input, not silently ignored. setting: the setting
    that chose the backend, named by the error."""
    if backend == "mavsdk" and (source_system, source_component) != (GCS_SYSTEM_ID, GCS_COMPONENT_ID):
        raise BridgeUsageError(Named("{name} mavsdk: MAVSDK sends as its own ground station (system 245), so "
                                     "{gcs_sysid} {0} / {gcs_compid} {1} cannot apply; leave them at their defaults "
                                     "or use missionplan's own uploader", source_system, source_component,
                                     name=setting))


def open_backend(backend: str, url: str, sysid: int, compid: int = AUTOPILOT_COMPONENT_ID,
                 key: SigningKey | None = None, timeouts: Timeouts | None = None,
                 connect_timeout: float = 10.0, link: Any = None, source_system: int = GCS_SYSTEM_ID,
                 source_component: int = GCS_COMPONENT_ID) -> MissionBackend:
    """Connect (or, pymavlink only, use `link`, a shared link's view) as ground station
    (source_system, source_component) and wait for the vehicle's heartbeat; BridgeError naming the
    system id on time-out."""
    check_gcs_identity(backend, source_system, source_component)
    if backend == "pymavlink":
        return PymavlinkBackend(url, sysid, compid, key, timeouts, connect_timeout, link, source_system,
                                source_component)
    if backend == "mavsdk":
        from .mavsdk_backend import MavsdkBackend  # the native library loads only when asked for

        return MavsdkBackend(url, sysid, compid, key, timeouts, connect_timeout)
    raise BridgeUsageError(Named("{backend} {0}: unknown backend (choose {1})", backend, " or ".join(BACKENDS)))


class VerifyError(BridgeError):
    """The read-back differs from what was sent."""


@dataclass
class PartReport:
    mission_type: MissionType
    items: int          # items of the mission file (ArduPilot's home item not counted)
    wire_items: int     # items on the wire (with the home placeholder)
    verified: bool
    read_back_by: str = ""
    unsupported: bool = False  # the vehicle has no such list (MAV_MISSION_UNSUPPORTED): it holds none


@dataclass
class UploadReport:
    sysid: int
    flavour: str
    backend: str
    parts: list[PartReport] = field(default_factory=list)
    params: list[str] = field(default_factory=list)  # each parameter, one phrase: "set NAME = ...", or why not
    seconds: float = 0.0

    @property
    def items(self) -> int:
        return sum(p.items for p in self.parts)

    @property
    def verified(self) -> bool:
        return bool(self.parts) and all(p.verified for p in self.parts)

    def summary(self) -> str:
        """The final line the CLI prints."""
        counts = ", ".join(f"{p.items} {p.mission_type.label}" if p.items or p.mission_type == MissionType.MISSION
                           else f"no {p.mission_type.label}" for p in self.parts)
        if self.verified:
            readers = sorted({p.read_back_by for p in self.parts if p.read_back_by})
            how = f"verified by read-back ({' and '.join(readers)})"
        else:
            how = "not verified (--no-verify)"
        params = "".join(f"; {text}" for text in self.params)
        return (f"uploaded {self.items} items ({counts}) to vehicle {self.sysid} ({self.flavour}, {self.backend}); "
                f"{how}{params}; {self.seconds:.2f} s")


ProgressFactory = Callable[[str, int], ProgressFn | None]  # (label, total) -> progress callback


def read_back_differences(backend: MissionBackend, mission_type: int, wire: list[WireItem],
                          progress: ProgressFn | None = None) -> list[str]:
    """Download what the vehicle holds and compare it with `wire` item by item by the flavour's rule
    (formats.readback.stored_form; ArduPilot's own home item skipped); an empty list when it holds
    exactly that."""
    got = backend.download(mission_type, progress)
    flavour = backend.vehicle.flavour
    skip_home = flavour.has_home_item(mission_type)
    if skip_home and len(wire) <= 1:
        # A cleared mission: ArduCopter then reports 0 items, or home alone once it has one (SITL).
        extra = len(got) - 1 if got else 0
        return [f"the vehicle still holds {extra} mission items after clearing"] if extra > 0 else []
    return compare_wire(wire, got, skip_home=skip_home, flavour=flavour)


def plan_parts(parts: list[Mission]) -> list[Mission]:
    """Mission, fence and rally, in that order: the lists given, and an empty one for each type missing
    (an upload leaves the vehicle holding exactly the file's three lists, so a missing one is cleared)."""
    by_type = {MissionType(p.mission_type): p for p in parts}
    return [by_type.get(t, Mission(mission_type=t)) for t in PLAN_TYPES]


def _send_part(backend: MissionBackend, mtype: MissionType, part: Mission, wire: list[WireItem],
               progress: ProgressFactory | None) -> tuple[bool, bool]:
    """Upload (or, for an empty list, clear) one list: (unsupported, unconfirmed).

    An empty mission is cleared too, not sent as a lone home item: ArduCopter answers such an upload
    by holding two items (measured on SITL), and MISSION_CLEAR_ALL is what every autopilot serves."""
    try:
        if not part.items:
            backend.clear(mtype)
        else:
            backend.upload(mtype, wire, progress(f"upload {mtype.label}", len(wire)) if progress else None)
    except UploadUnconfirmed:
        return False, True
    except MissionTransferError as err:
        if not part.items and err.result == mavlink.MAV_MISSION_UNSUPPORTED:
            return True, False  # a vehicle without fences (rally points) holds none: that is what was asked
        raise
    return False, False


def set_plan_params(backend: MissionBackend, mission: Mission, terrain_spacing: int | None = None) -> list[str]:
    """Set what the vehicle needs to fly `mission` as written (link.params): WPNAV_RADIUS on an ArduPilot
    multirotor, and for a mission with terrain-frame waypoints the terrain parameters and RTL_ALT_TYPE
    (terrain_plan_settings); one phrase per parameter for the report ("set WPNAV_RADIUS = ..."). RTL_ALT_TYPE alone may be missing
    on the vehicle (an ArduCopter older than the parameter): said, not fatal."""
    vehicle = backend.vehicle
    radius: ParamSetting | None = acceptance_radius_setting(vehicle, mission)
    settings = ([radius] if radius is not None else []) + terrain_plan_settings(vehicle, mission, terrain_spacing)
    said = []
    for setting in settings:
        try:
            old, _ = backend.set_param(setting.name, setting.value)
        except BridgeError:
            if setting.name != RTL_ALT_TYPE:
                raise
            said.append(f"{RTL_ALT_TYPE} not set: the vehicle has no such parameter (its RTL altitude stays above "
                        "home)")
            continue
        said.append(f"set {setting.describe(old)}")
    return said


HOME_WAIT_S = 2.0  # how long upload waits for a PX4 vehicle's HOME_POSITION before skipping the start check


def vehicle_home(link: Any, sysid: int, seconds: float = HOME_WAIT_S) -> tuple[float, float] | None:
    """The vehicle's home (lat, lon), asked for with MAV_CMD_REQUEST_MESSAGE(HOME_POSITION); None
    when it has none yet or does not answer within `seconds`."""
    deadline = time.monotonic() + seconds
    asked = 0.0
    while time.monotonic() < deadline:
        if time.monotonic() - asked >= 0.5:
            link.mav.command_long_send(sysid, AUTOPILOT_COMPONENT_ID, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                       mavlink.MAVLINK_MSG_ID_HOME_POSITION, 0, 0, 0, 0, 0, 0)
            asked = time.monotonic()
        msg = link.recv(min(deadline, asked + 0.5))
        if msg is not None and msg.get_srcSystem() == sysid and msg.get_type() == "HOME_POSITION":
            return msg.latitude / 1e7, msg.longitude / 1e7
    return None


def px4_start_problems(backend: MissionBackend, parts: list[Mission]) -> str | None:
    """What a PX4 vehicle would do wrong with this plan from where it is (formats.px4_rules: refuse to start
    it, the first waypoint being MIS_DIST_1WP or more away; ignore its geofence, which leaves the
    vehicle's home out), as one phrase; None when all is well, or when the vehicle's home is not
    known (no link, no fix)."""
    link = getattr(backend, "link", None)
    if link is None or backend.vehicle.flavour is not Flavour.PX4:
        return None
    home = vehicle_home(link, backend.vehicle.sysid)
    if home is None:
        return None
    try:
        limit = ParamClient(link, backend.vehicle).get("MIS_DIST_1WP", tries=2, wait_s=0.5)
    except BridgeError:
        limit = MIS_DIST_1WP_DEFAULT
    mission, fence = (to_wire(p, Flavour.PX4) for p in parts[:2])
    refusals, unfenced = start_refusals(mission, home, limit), fence_problems(fence, home)
    if not refusals and not unfenced:
        return None
    what = []
    if refusals:
        what.append(f"would refuse to start this mission (\"{START_DENIED}\"): {'; '.join(refusals)}")
    if unfenced:
        what.append(f"would fly it without its geofence (\"{unfenced[0]}\")")
    return (f"vehicle {backend.vehicle.sysid} (px4) {' and '.join(what)}, from its home {home[0]:.7f}, "
            f"{home[1]:.7f}; put it at the plan's launch point, or plan from where it stands (docs/px4-missions.md)")


def upload_plan(backend: MissionBackend, parts: list[Mission], verify: bool = True,
                progress: ProgressFactory | None = None, set_params: bool = True,
                terrain_spacing: int | None = None) -> UploadReport:
    """Upload mission, fence and rally (an absent or empty fence / rally list is cleared on the vehicle)
    and, with verify, prove by read-back that the vehicle holds exactly those three lists, by the
    flavour's rule (formats.readback.stored_form). With set_params, first set what the vehicle needs to
    fly the plan as written (link.params: WPNAV_RADIUS on ArduCopter; the terrain parameters, TERRAIN_SPACING
    `terrain_spacing` among them, for terrain-frame waypoints)."""
    start = time.monotonic()
    vehicle = backend.vehicle
    report = UploadReport(sysid=vehicle.sysid, flavour=vehicle.flavour.value, backend=backend.name)
    parts = plan_parts(parts)
    # PX4 decides whether a mission can start when it gets it, from where it is: a plan for another
    # site would verify and then be refused at MISSION_START with no reason given.
    refusal = px4_start_problems(backend, parts)
    if refusal is not None:
        raise BridgeError(refusal)
    if set_params:
        report.params = set_plan_params(backend, parts[0], terrain_spacing)
    for part in parts:
        mtype = MissionType(part.mission_type)
        wire = to_wire(part, vehicle.flavour)
        unsupported, unconfirmed = _send_part(backend, mtype, part, wire, progress)
        verified = False
        reader = ""
        if (verify or unconfirmed) and not unsupported:
            problems = read_back_differences(backend, mtype, wire,
                                             progress(f"verify {mtype.label}", len(wire)) if progress else None)
            if problems:
                what = "accepted the" if not unconfirmed else "did not confirm the"
                raise VerifyError(f"vehicle {vehicle.sysid} {what} {mtype.label} but holds something else: "
                                  + "; ".join(problems))
            verified = verify
            reader = getattr(backend, "read_back_by", backend.name) if verify else ""
        elif verify:
            verified = True  # the vehicle has no such list at all, and none was asked for
        report.parts.append(PartReport(mtype, len(part.items), len(wire), verified, reader, unsupported))
    report.seconds = time.monotonic() - start
    return report


def download_plan(backend: MissionBackend, mission_types: list[MissionType],
                  progress: ProgressFactory | None = None) -> list[Mission]:
    """Each requested list as the vehicle holds it, in the model's terms (home split off on ArduPilot)."""
    out: list[Mission] = []
    for mtype in mission_types:
        items = backend.download(mtype, progress(f"download {mtype.label}", 0) if progress else None)
        out.append(from_wire(items, backend.vehicle.flavour, mtype))
    return out


def clear_plan(backend: MissionBackend) -> str:
    """Clear the mission, fence and rally lists and read each back empty; the one-line report.

    One MISSION_CLEAR_ALL per list rather than MAV_MISSION_TYPE_ALL, which not every autopilot serves;
    a vehicle without fence or rally support (MAV_MISSION_UNSUPPORTED) has none to clear.
    """
    start = time.monotonic()
    vehicle = backend.vehicle
    cleared: list[str] = []
    for mtype in PLAN_TYPES:
        try:
            backend.clear(mtype)
        except MissionTransferError as err:
            if err.result == mavlink.MAV_MISSION_UNSUPPORTED and mtype != MissionType.MISSION:
                continue
            raise
        left = download_plan(backend, [mtype])[0]
        if left.items:
            raise VerifyError(f"vehicle {vehicle.sysid} acknowledged clearing its {mtype.label} but still holds "
                              f"{len(left.items)} {mtype.label} items")
        cleared.append(mtype.label)
    names = ", ".join(cleared[:-1]) + " and " + cleared[-1] if len(cleared) > 1 else cleared[0]
    return (f"cleared the {names} of vehicle {vehicle.sysid} ({vehicle.flavour.value}); verified empty "
            f"by read-back; {time.monotonic() - start:.2f} s")
