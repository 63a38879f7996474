"""Backend-neutral mission upload with read-back verification, and the pymavlink backend.

Owns:
- MissionBackend: what a backend offers (upload / download / clear / set-current of wire items for
  one vehicle), with two implementations: PymavlinkBackend here and MavsdkBackend in mavsdk_backend;
- open_backend: connect by URL, find the vehicle by system id, learn its flavour;
- read_back_differences: download a list and compare it with what was sent;
- upload_plan: turn the mission (and fence / rally lists, if any) into the vehicle's wire items by
  flavour, upload each, read each back and compare item by item (ArduPilot's item 0 is its home and
  is skipped). It succeeds only when the vehicle holds exactly what was sent.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from .errors import BridgeError, BridgeUsageError
from .link import AUTOPILOT_COMPONENT_ID, Link, VehicleInfo, wait_vehicle
from .mission import Mission, MissionType, WireItem, compare_wire, from_wire, to_wire
from .protocol import MissionClient, ProgressFn, Timeouts
from .signing import SigningKey

BACKENDS = ("pymavlink", "mavsdk")


class MissionBackend(Protocol):
    """One vehicle reached through one link."""

    name: str
    vehicle: VehicleInfo

    def upload(self, mission_type: int, items: list[WireItem], progress: ProgressFn | None = None) -> None: ...

    def download(self, mission_type: int, progress: ProgressFn | None = None) -> list[WireItem]: ...

    def clear(self, mission_type: int = MissionType.MISSION) -> None: ...

    def set_current(self, seq: int) -> None: ...

    def close(self) -> None: ...


class PymavlinkBackend:
    """The default backend: our own mission protocol (bridge.protocol) over a pymavlink link."""

    name = "pymavlink"

    def __init__(self, url: str, sysid: int, compid: int = AUTOPILOT_COMPONENT_ID, key: SigningKey | None = None,
                 timeouts: Timeouts | None = None, connect_timeout: float = 10.0) -> None:
        self.link = Link(url, key)
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

    def close(self) -> None:
        self.link.close()

    def __enter__(self) -> PymavlinkBackend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_backend(backend: str, url: str, sysid: int, compid: int = AUTOPILOT_COMPONENT_ID,
                 key: SigningKey | None = None, timeouts: Timeouts | None = None,
                 connect_timeout: float = 10.0) -> MissionBackend:
    """Connect and wait for the vehicle's heartbeat; BridgeError naming the system id on time-out."""
    if backend == "pymavlink":
        return PymavlinkBackend(url, sysid, compid, key, timeouts, connect_timeout)
    if backend == "mavsdk":
        from .mavsdk_backend import MavsdkBackend  # the native library loads only when asked for

        return MavsdkBackend(url, sysid, compid, key, timeouts, connect_timeout)
    raise BridgeUsageError(f"--backend {backend}: unknown backend (choose {' or '.join(BACKENDS)})")


class VerifyError(BridgeError):
    """The read-back differs from what was sent."""


@dataclass
class PartReport:
    mission_type: MissionType
    items: int          # items of the mission file (ArduPilot's home item not counted)
    wire_items: int     # items on the wire (with the home placeholder)
    verified: bool
    read_back_by: str = ""


@dataclass
class UploadReport:
    sysid: int
    flavour: str
    backend: str
    parts: list[PartReport] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def items(self) -> int:
        return sum(p.items for p in self.parts)

    @property
    def verified(self) -> bool:
        return bool(self.parts) and all(p.verified for p in self.parts)

    def summary(self) -> str:
        """The final line the CLI prints."""
        counts = ", ".join(f"{p.items} {p.mission_type.label}" for p in self.parts)
        if self.verified:
            readers = sorted({p.read_back_by for p in self.parts})
            how = f"verified by read-back ({' and '.join(readers)})"
        else:
            how = "not verified (--no-verify)"
        return (f"uploaded {self.items} items ({counts}) to vehicle {self.sysid} ({self.flavour}, {self.backend}); "
                f"{how}; {self.seconds:.2f} s")


ProgressFactory = Callable[[str, int], ProgressFn | None]  # (label, total) -> progress callback


def read_back_differences(backend: MissionBackend, mission_type: int, wire: list[WireItem],
                          progress: ProgressFn | None = None) -> list[str]:
    """Download what the vehicle holds and compare it with `wire` item by item by the flavour's rule
    (bridge.mission.stored_form; ArduPilot's own home item skipped); an empty list when it holds
    exactly that."""
    got = backend.download(mission_type, progress)
    flavour = backend.vehicle.flavour
    return compare_wire(wire, got, skip_home=flavour.has_home_item(mission_type), flavour=flavour)


def upload_plan(backend: MissionBackend, parts: list[Mission], verify: bool = True,
                progress: ProgressFactory | None = None) -> UploadReport:
    """Upload each part (mission, fence, rally) and, with verify, prove the vehicle holds it exactly."""
    start = time.monotonic()
    vehicle = backend.vehicle
    report = UploadReport(sysid=vehicle.sysid, flavour=vehicle.flavour.value, backend=backend.name)
    for part in parts:
        mtype = MissionType(part.mission_type)
        wire = to_wire(part, vehicle.flavour)
        label = f"upload {mtype.label}"
        backend.upload(mtype, wire, progress(label, len(wire)) if progress else None)
        verified = False
        reader = ""
        if verify:
            problems = read_back_differences(backend, mtype, wire,
                                             progress(f"verify {mtype.label}", len(wire)) if progress else None)
            if problems:
                raise VerifyError(f"vehicle {vehicle.sysid} accepted the {mtype.label} but holds something else: "
                                  + "; ".join(problems))
            verified = True
            reader = getattr(backend, "read_back_by", backend.name)
        report.parts.append(PartReport(mtype, len(part.items), len(wire), verified, reader))
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
