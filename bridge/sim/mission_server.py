"""The vehicle side of the MAVLink mission protocol in the mock autopilot, for mission, fence and rally.

Owns, for one mock vehicle (mock_vehicle), its stored lists (one per mission_type) and their transfers: upload
with re-requests on a timer and a give-up time-out (the old list stays until an upload completes), download of
any in-range item in any order, clear-all, set-current (MISSION_SET_CURRENT, and DO_SET_MISSION_CURRENT through
vehicle_commands), and how a mission replaced while the vehicle flies is taken. The ArduPilot flavour does what
ArduCopter SITL does: it stores items as formats.readback.ardupilot_stored says (NAV_WAYPOINT keeps only param1,
DO_* come back in frame 0, ...), keeps its home as item 0 (0, 0, 0 until its GPS has a fix), re-requests after
1 s, answers an item it did not ask for with INVALID_SEQUENCE and one after the upload completed with ERROR, and
marks no item current in a download. The PX4 flavour does what PX4 SIH does with missions (formats.px4_rules,
measured; sitl_tests/test_mock_vs_px4.py keeps it honest): PX4's frame / command matrix and result codes, its
stored form (3 -> 6, 0 -> 5, no pass radius, float32-radian yaws), the `current` flag on its active item and on
item 0 of fence and rally, the legacy MISSION_REQUEST until the ground station speaks *_INT (an error answer flips
it), the reasons it refuses to start the stored mission (start_refusals: before its GPS fix, or when the first
waypoint is MIS_DIST_1WP or more from its home; vehicle_commands answers MISSION_START with them), and "Geofence
invalid, doesn't contain Home position" after a fence without its home. A mission replaced while the vehicle flies
is taken as each autopilot took it (docs/live-retasking.md, _replaced_in_flight): ArduPilot keeps its item and
restarts it, PX4 goes to the item flagged current. Another ground station's transfer: while one (sysid, compid)
uploads, ArduPilot's MissionItemProtocol answers another's MISSION_COUNT and MISSION_CLEAR_ALL with
MAV_MISSION_DENIED (clear-all then also ERROR), its items with INVALID_SEQUENCE or DENIED, and any
MISSION_REQUEST_LIST / MISSION_REQUEST_INT with DENIED, until the upload completes or times out (8 s without an
item). A reboot forgets every list (mock_vehicle's reboot fault, also MockVehicle.reboot_after_items during an
upload).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from ..formats.mission_items import GLOBAL_FRAMES, Flavour, MissionType, WireItem, encode_xy
from ..formats.px4_rules import (GEOFENCE_WITHOUT_HOME, MIS_DIST_1WP_DEFAULT, fence_problems, item_result,
                                 px4_stored, start_refusals)
from ..formats.readback import ardupilot_stored, is_positional
from ..link.connection import mavlink
from .vehicle_part import VehiclePart

MISSION_COMMANDS_REJECTED = range(5000, 6000)  # fence and rally commands do not belong in a mission
FENCE_COMMANDS = frozenset({mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                            mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
                            mavlink.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION})


@dataclass
class Upload:
    """An upload in progress: from whom, how many items it announced, those received, when it last moved."""

    mission_type: int
    count: int
    peer: tuple[int, int]
    received: list[WireItem]
    last_sent: float
    last_progress: float


class MissionServer(VehiclePart):
    """One vehicle's stored mission, fence and rally lists, and its side of their transfers."""

    HANDLERS = {
        "MISSION_COUNT": "_on_count",
        "MISSION_ITEM_INT": "_on_item",
        "MISSION_ITEM": "_on_item",
        "MISSION_ACK": "_on_gcs_ack",
        "MISSION_REQUEST_LIST": "_on_request_list",
        "MISSION_REQUEST_INT": "_on_request",
        "MISSION_REQUEST": "_on_request",
        "MISSION_CLEAR_ALL": "_on_clear_all",
        "MISSION_SET_CURRENT": "_on_set_current",
    }

    def __init__(self, vehicle: Any) -> None:
        super().__init__(vehicle)
        # Counted for the tests and the bench; a reboot keeps them.
        self.uploads_completed = 0
        self.uploads_failed = 0
        self.invalid_sequence_acks = 0  # INVALID_SEQUENCE answers to items it did not ask for
        self.stray_item_acks = 0        # ERROR answers to items that came after an upload completed
        self.denied_transfers = 0  # DENIED answers to another ground station during an upload
        self.mission_checked_at = 0.0  # PX4: MISSION_START is refused before then (VehicleOptions.mission_check_s)

    def on_boot(self) -> None:
        """A (re)boot forgets every list (ArduPilot's home item stays) and any upload, and loads the flight."""
        self.stores: dict[int, list[WireItem]] = {MissionType.MISSION: [], MissionType.FENCE: [], MissionType.RALLY: []}
        if self.flavour.has_home_item(MissionType.MISSION):
            self.stores[MissionType.MISSION] = [self._home_item()]
        self.upload: Upload | None = None
        self._flight_stale = False  # ArduPilot: flying an item of a mission replaced since (_replaced_in_flight)
        self._restart_on_auto = False  # ArduPilot: its item cut off by a shorter mission while out of AUTO
        # PX4 asks with the legacy MISSION_REQUEST until the ground station has used an *_INT message.
        self._int_mode = False
        self.last_completed: tuple[int, int, tuple[int, int]] | None = None  # type, count, peer
        self.load_flight()

    def tick(self, now: float) -> None:
        """The upload's timers: give a stalled upload up, or ask again for the item it waits for."""
        up = self.upload
        if up is None:
            return
        if now - up.last_progress >= self.options.upload_timeout:
            self.upload = None
            self.uploads_failed += 1
            self._ack(up.peer, up.mission_type, mavlink.MAV_MISSION_OPERATION_CANCELLED)  # the old mission stays
            return
        if now - up.last_sent >= self.options.request_interval:
            self._request(up, now)

    # ------------------------------------------------------------------------------ the stored lists
    @property
    def first_mission_seq(self) -> int:
        return 1 if self.flavour.has_home_item(MissionType.MISSION) else 0

    @property
    def has_mission(self) -> bool:
        """Whether the stored mission has an item to fly (ArduPilot's home item does not count)."""
        return len(self.stores[MissionType.MISSION]) > self.first_mission_seq

    def mission(self, mission_type: int = MissionType.MISSION) -> list[WireItem]:
        items = list(self.stores[int(mission_type)])
        if items and self.flavour.has_home_item(int(mission_type)):
            items[0] = self._home_item()  # the home as it is now
        return items

    def _home_item(self) -> WireItem:
        lat, lon, alt = self.options.home if self.vehicle.has_fix else (0.0, 0.0, 0.0)
        frame = mavlink.MAV_FRAME_GLOBAL
        return WireItem(seq=0, frame=frame, command=mavlink.MAV_CMD_NAV_WAYPOINT, current=0, autocontinue=1,
                        param1=0.0, param2=0.0, param3=0.0, param4=0.0, x=encode_xy(frame, lat),
                        y=encode_xy(frame, lon), z=float(alt), mission_type=int(MissionType.MISSION))

    def load_flight(self) -> None:
        """The flight (mock_flight) takes the stored mission."""
        self.vehicle.flight.load(self.stores[MissionType.MISSION], self.first_mission_seq)

    def start_refusals(self) -> list[str]:
        """Why PX4 would refuse to start the stored mission (formats.px4_rules), from this vehicle's home;
        empty for other flavours and for a mission PX4 would start."""
        if self.flavour is not Flavour.PX4:
            return []
        if not self.vehicle.ready:  # measured on SIH: until "Ready for takeoff!" every start is "No valid mission"
            return ["no home position yet"]
        return start_refusals(self.stores[MissionType.MISSION], self.options.home[:2],
                              self.vehicle.params.get("MIS_DIST_1WP", MIS_DIST_1WP_DEFAULT))

    # ------------------------------------------------------------------------------ sending
    def _ack(self, peer: tuple[int, int], mission_type: int, result: int) -> None:
        self.mav.mission_ack_send(peer[0], peer[1], result, mission_type)

    def _request(self, up: Upload, now: float) -> None:
        seq = len(up.received)
        if self.options.legacy_requests or (self.flavour is Flavour.PX4 and not self._int_mode):
            self.mav.mission_request_send(up.peer[0], up.peer[1], seq, up.mission_type)
        else:
            self.mav.mission_request_int_send(up.peer[0], up.peer[1], seq, up.mission_type)
        up.last_sent = now

    # ------------------------------------------------------------------------------ upload
    def _on_count(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in self.stores:
            self._ack(peer, mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        if self.upload is not None and self.upload.peer != peer:
            # ArduPilot's MissionItemProtocol::cancel_upload: another (sysid, compid) is uploading; only it
            # may restart its upload, the others are DENIED until it completes or times out.
            self.denied_transfers += 1
            self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)
            return
        count = int(msg.count)
        if count > self.options.max_items:
            self.upload = None
            self._ack(peer, mission_type, mavlink.MAV_MISSION_NO_SPACE)
            return
        if count == 0:
            self.upload = None
            self._commit(mission_type, [], peer, now)
            return
        # A new (or repeated) count starts the requests over from item 0.
        self.upload = Upload(mission_type, count, peer, [], last_sent=now, last_progress=now)
        self._request(self.upload, now)

    def failed(self, msg: Any, peer: tuple[int, int]) -> None:
        """Answering a mission message raised (logged by VehiclePart.handle): an upload from this peer is
        dropped (the old list stays) and answered with MAV_MISSION_ERROR, as ArduPilot answers an item it
        cannot take; any other transfer message gets the same ERROR."""
        mission_type = int(getattr(msg, "mission_type", 0))
        up = self.upload
        if up is not None and up.peer == peer:
            self.upload = None
            self.uploads_failed += 1
            mission_type = up.mission_type
        self._ack(peer, mission_type, mavlink.MAV_MISSION_ERROR)

    def _check_item(self, item: WireItem) -> int:
        """The MAV_MISSION_RESULT an item earns: ACCEPTED or why not."""
        frame, command = item.frame, item.command
        if self.flavour is Flavour.ARDUPILOT and item.mission_type != MissionType.FENCE:
            result = ardupilot_item_result(item, self.upload.count if self.upload is not None else 0)
            if result != mavlink.MAV_MISSION_ACCEPTED:
                return result
        if self.flavour is Flavour.PX4:
            result = item_result(item)  # PX4's frame / command matrix, measured on SIH
            if result != mavlink.MAV_MISSION_ACCEPTED:
                return result
        elif item.mission_type == MissionType.FENCE:
            if command not in FENCE_COMMANDS:
                return mavlink.MAV_MISSION_UNSUPPORTED
        elif item.mission_type == MissionType.RALLY:
            if command != mavlink.MAV_CMD_NAV_RALLY_POINT:
                return mavlink.MAV_MISSION_UNSUPPORTED
        elif command in MISSION_COMMANDS_REJECTED:
            return mavlink.MAV_MISSION_UNSUPPORTED
        if frame not in GLOBAL_FRAMES and frame != mavlink.MAV_FRAME_MISSION:
            return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
        if self.flavour is not Flavour.GENERIC:
            # ArduPilot's own checks are above; PX4 takes a latitude of 91 degrees, an altitude of 1e38 m and an
            # infinite parameter and stores them as sent (measured on PX4 SIH v1.15.4: its upload checks none).
            return mavlink.MAV_MISSION_ACCEPTED
        if frame in GLOBAL_FRAMES:
            if abs(item.x) > 900_000_000:
                return mavlink.MAV_MISSION_INVALID_PARAM5_X
            if abs(item.y) > 1_800_000_000:
                return mavlink.MAV_MISSION_INVALID_PARAM6_Y
        if not all(math.isfinite(v) or math.isnan(v) for v in (item.param1, item.param2, item.param3, item.param4)):
            return mavlink.MAV_MISSION_ERROR
        return mavlink.MAV_MISSION_ACCEPTED

    def _on_item(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        self._int_mode = msg.get_type() == "MISSION_ITEM_INT"
        item = WireItem.from_message(msg)
        up = self.upload
        if up is None or up.peer != peer or up.mission_type != item.mission_type:
            done = self.last_completed
            if self.flavour is Flavour.ARDUPILOT:
                if up is not None and up.peer != peer and up.mission_type == item.mission_type:
                    # MissionItemProtocol::handle_mission_item: the sequence first, then the sender
                    self.denied_transfers += item.seq == len(up.received)
                    self._ack(peer, item.mission_type, mavlink.MAV_MISSION_INVALID_SEQUENCE
                              if item.seq != len(up.received) else mavlink.MAV_MISSION_DENIED)
                    return
                if up is None:
                    # ArduPilot: "mission item received while not receiving", even for a copy of the
                    # last item of an upload that just completed (its ACCEPTED is not repeated).
                    self.stray_item_acks += done is not None
                    self._ack(peer, item.mission_type, mavlink.MAV_MISSION_ERROR)
                return
            if done is not None and done[0] == item.mission_type and done[2] == peer and item.seq < done[1]:
                if item.seq == done[1] - 1:
                    # the last item again: our ACK was lost
                    self._ack(peer, item.mission_type, mavlink.MAV_MISSION_ACCEPTED)
                return  # a late copy of an item of the finished upload
            if up is None:
                # no upload in progress (after a reboot, say)
                self._ack(peer, item.mission_type, mavlink.MAV_MISSION_ERROR)
            return
        if item.seq != len(up.received):
            if self.flavour is Flavour.ARDUPILOT:  # ArduPilot complains about any item it did not ask for
                self.invalid_sequence_acks += 1
                self._ack(peer, up.mission_type, mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return  # out of order or repeated: the timer re-requests what is missing
        result = self._check_item(item)
        if result != mavlink.MAV_MISSION_ACCEPTED:
            self.upload = None
            self.uploads_failed += 1
            self._ack(peer, up.mission_type, result)
            return
        up.received.append(item)
        up.last_progress = now
        vehicle = self.vehicle
        if vehicle.reboot_after_items is not None and len(up.received) >= vehicle.reboot_after_items:
            vehicle.reboot_after_items = None
            vehicle.reboot(now)  # the reboot fault during an upload (MockAutopilot.reboot_after_items)
            return
        if len(up.received) == up.count:
            self.upload = None
            if (self.flavour is Flavour.ARDUPILOT and up.mission_type == MissionType.FENCE
                    and not all(_latlon_valid(it) for it in up.received)):
                # ArduPilot checks its fence when the last point has come and answers ERROR (measured on SITL:
                # a vertex at latitude 91); the old fence stays.
                self.uploads_failed += 1
                self._ack(peer, up.mission_type, mavlink.MAV_MISSION_ERROR)
                return
            self._commit(up.mission_type, up.received, peer, now)
        else:
            self._request(up, now)

    def _commit(self, mission_type: int, items: list[WireItem], peer: tuple[int, int], now: float) -> None:
        """The upload completed: the new list replaces the old one."""
        stored = [self._stored(replace(it, current=0)) for it in items]
        if self.flavour.has_home_item(mission_type):
            # ArduPilot keeps its own home as item 0, whatever was uploaded there.
            stored = [self._home_item()] + stored[1:]
        self.stores[mission_type] = stored
        self.uploads_completed += 1
        self.last_completed = (mission_type, len(items), peer)
        telemetry = self.vehicle.telemetry
        if mission_type == MissionType.MISSION:
            self.mission_checked_at = now + (self.options.mission_check_s or 0.0) / self.options.speedup
            s = self.vehicle.flight.state
            if s.armed and not s.on_ground:
                self._replaced_in_flight(items)
            else:
                s.current = self.first_mission_seq
                s.mission_done = False
                self.load_flight()
        self._ack(peer, mission_type, mavlink.MAV_MISSION_ACCEPTED)
        telemetry.send_mission_current()
        if mission_type == MissionType.FENCE and self.flavour is Flavour.PX4 and fence_problems(
                stored, self.options.home[:2]):
            telemetry.send_text(GEOFENCE_WITHOUT_HOME)  # as PX4 says it right after such a fence upload

    def _stored(self, item: WireItem) -> WireItem:
        # ArduPilot keeps what its storage has room for (formats.readback.ardupilot_stored, measured on
        # ArduCopter SITL: no NAV_WAYPOINT param2, frame 0 for DO_* ...); PX4 what formats.px4_rules.px4_stored
        # says (frames 3 -> 6, 0 -> 5, no pass radius; measured on PX4 SIH); others keep what they got.
        if self.flavour is Flavour.ARDUPILOT:
            stored = ardupilot_stored(item)
            hold = item.param1
            if (item.command == mavlink.MAV_CMD_NAV_WAYPOINT and item.mission_type == MissionType.MISSION
                    and math.isfinite(hold) and not 0.0 <= hold < 65_536.0):
                # Its uint16 hold time keeps the low 16 bits (1e6 s came back as 16,960 s on SITL); the read-back
                # rule does not take that as legal, so an upload of such a hold fails its verification.
                stored = replace(stored, param1=float((int(hold) & 0xFFFF) if abs(hold) < 2**31 else 0))
            return stored
        return px4_stored(item) if self.flavour is Flavour.PX4 else item

    def _on_gcs_ack(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        up = self.upload
        if up is not None and up.peer == peer and int(getattr(msg, "mission_type", 0)) == up.mission_type:
            if self.flavour is Flavour.PX4 \
                    and int(msg.type) not in (mavlink.MAV_MISSION_ACCEPTED, mavlink.MAV_MISSION_OPERATION_CANCELLED):
                # PX4 (mavlink_mission.cpp): an error answer to its request means "ask the other way":
                # MAVSDK refuses the legacy MISSION_REQUEST, and PX4 asks again with MISSION_REQUEST_INT.
                self._int_mode = not self._int_mode
                self._request(up, now)
                return
            if int(msg.type) != mavlink.MAV_MISSION_ACCEPTED:
                self.upload = None  # the ground station cancelled: keep the old mission
                self.uploads_failed += 1

    # ------------------------------------------------------------------------------ download
    def _receiving(self, mission_type: int) -> bool:
        """ArduPilot: an upload of this type is in progress (MissionItemProtocol `receiving`)."""
        up = self.upload
        return self.flavour is Flavour.ARDUPILOT and up is not None and up.mission_type == mission_type

    def _on_request_list(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in self.stores:
            self._ack(peer, mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        if self._receiving(mission_type):  # "someone is uploading a mission; reject fetching of points"
            self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)
            return
        self.mav.mission_count_send(peer[0], peer[1], len(self.stores[mission_type]), mission_type)

    def _on_request(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        store = self.stores.get(mission_type)
        if store is None:
            self._ack(peer, mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        seq = int(msg.seq)
        self._int_mode = msg.get_type() == "MISSION_REQUEST_INT"
        if self._int_mode and self._receiving(mission_type):  # ArduPilot checks this for the *_INT request only
            self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)
            return
        if not 0 <= seq < len(store):
            self._ack(peer, mission_type, mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return
        stored = self._home_item() if seq == 0 and self.flavour.has_home_item(mission_type) else store[seq]
        # ArduPilot marks no item current in a download; PX4 marks the one it is at (and item 0 of its
        # fence and rally lists).
        flagged = self.vehicle.flight.state.current if mission_type == 0 else 0 if self.flavour is Flavour.PX4 else -1
        current = self.flavour is not Flavour.ARDUPILOT and seq == flagged
        item = replace(stored, seq=seq, current=int(current))
        if msg.get_type() == "MISSION_REQUEST":  # legacy request: legacy float item
            x = item.x / 1e7 if item.frame in GLOBAL_FRAMES else float(item.x)
            y = item.y / 1e7 if item.frame in GLOBAL_FRAMES else float(item.y)
            self.mav.mission_item_send(peer[0], peer[1], seq, item.frame, item.command, item.current,
                                       item.autocontinue, item.param1, item.param2, item.param3, item.param4,
                                       x, y, item.z, mission_type)
        else:
            self.mav.mission_item_int_send(peer[0], peer[1], **item.fields())

    # ------------------------------------------------------------------------------ clear, set current
    def _on_clear_all(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        types = list(self.stores) if mission_type == MissionType.ALL else [mission_type]
        if any(t not in self.stores for t in types):
            self._ack(peer, mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        up = self.upload
        if self.flavour is Flavour.ARDUPILOT and up is not None and up.mission_type in types:
            if up.peer != peer:  # MissionItemProtocol::handle_mission_clear_all: cancel_upload refused
                self.denied_transfers += 1
                self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)
                self._ack(peer, mission_type, mavlink.MAV_MISSION_ERROR)
                return
            self.upload = None  # its own upload: cancelled, then cleared
        s = self.vehicle.flight.state
        if s.armed and s.mode == "AUTO" and MissionType.MISSION in types:
            self._ack(peer, mission_type, mavlink.MAV_MISSION_DENIED)  # not while flying it
            return
        for t in types:
            self.stores[t] = [self._home_item()] if self.flavour.has_home_item(t) else []
        if MissionType.MISSION in types:
            s.current = self.first_mission_seq
            self.load_flight()
        self._ack(peer, mission_type, mavlink.MAV_MISSION_ACCEPTED)

    def _replaced_in_flight(self, received: list[WireItem]) -> None:
        """A mission replaced while the vehicle flies (measured: docs/live-retasking.md). ArduPilot keeps
        its current index; flying its mission, it restarts the item now there when the navigation
        items from it on changed ("Auto mission changed, restarted command"), and past the new end it
        finishes the item it flies ("... but failed to restart command"); out of AUTO, it resumes there
        (from the first item when that index is gone). PX4 takes the item flagged `current` in the
        upload (else keeps its index, within the new mission) and, in mission mode, flies from it at once."""
        flight, telemetry = self.vehicle.flight, self.vehicle.telemetry
        s = flight.state
        flying_mission = s.mode == "AUTO" and not s.mission_done
        new = self.stores[MissionType.MISSION]
        old, index = flight.items, s.current
        self._restart_on_auto = False
        if self.flavour is not Flavour.ARDUPILOT:
            if new == old:
                return  # the same mission (PX4: the same checksum): nothing changes
            flagged = [it.seq for it in received if it.current]
            target = flagged[-1] if flagged else min(index, len(new) - 1)
            self.load_flight()
            s.current = target
            s.mission_done = False
            if flying_mission:
                telemetry.publish(flight.set_current(target))
            return
        if index >= len(new):
            if flying_mission:  # the item flown stays loaded; after it the mission is complete
                telemetry.send_text("Auto mission changed but failed to restart command")
                flight.last_seq = index
                self._flight_stale = True
            else:
                self.load_flight()
                s.current = index  # still reported (MISSION_CURRENT), as SITL does, until set or resumed
                self._restart_on_auto = True  # AP_Mission::resume: its item is gone, start() again
            return
        self.load_flight()
        s.current = index
        if flying_mission and _next_nav(old, index) != _next_nav(new, index):
            telemetry.send_text("Auto mission changed, restarted command")
            telemetry.publish(flight.set_current(index))

    def resume_on_auto(self) -> None:
        """AUTO entered: ArduPilot's item cut off by a shorter mission while out of AUTO is gone, so its
        mission starts over from the first item (AP_Mission::resume)."""
        if self._restart_on_auto:
            self._restart_on_auto = False
            self.vehicle.flight.set_current(self.first_mission_seq)

    def set_current(self, seq: int) -> bool:
        """Fly the mission from item `seq` (MISSION_SET_CURRENT, DO_SET_MISSION_CURRENT); False when it has none."""
        if not 0 <= seq < len(self.stores[MissionType.MISSION]):
            return False
        flight = self.vehicle.flight
        if self._flight_stale:  # still finishing an item of the replaced mission: the new one from now on
            self._flight_stale = False
            self.load_flight()
            flight.last_seq = None
        self._restart_on_auto = False
        flight.set_current(max(seq, self.first_mission_seq))
        self.vehicle.telemetry.send_mission_current()
        return True

    def _on_set_current(self, msg: Any, peer: tuple[int, int], now: float) -> None:
        if not self.set_current(int(msg.seq)):
            self.vehicle.telemetry.send_mission_current()  # unchanged: the ground station sees its request failed


# What ArduCopter answers to a mission or rally item it cannot store (AP_Mission::sanity_check_params and
# mavlink_int_to_mission_cmd, MissionItemProtocol_Waypoints; each answer measured on ArduCopter 4.7-dev SITL
# by sitl_tests/test_mock_vs_arducopter.py): a NaN parameter where the command takes none (only param4 of
# NAV_WAYPOINT, NAV_LAND, NAV_TAKEOFF, NAV_VTOL_TAKEOFF and params 3-4 of NAV_VTOL_LAND may be NaN) or an
# infinite one: MAV_MISSION_INVALID_PARAM1..4; for an item with a position, a latitude beyond +-90 degrees:
# INVALID_PARAM5_X, a longitude beyond +-180: INVALID_PARAM6_Y, an altitude that is NaN or 83 km or more either
# way (its Location keeps 24-bit centimetres: 1e38 m and -1e9 m alike): INVALID_PARAM7; a DO_JUMP to item 0
# or past the upload's last item: MAV_MISSION_ERROR. Items without a position keep no x / y / z, so theirs
# are not checked (an RTL with z = 1e38 is taken).
ARDUPILOT_ALT_MAX_M = 83_000.0  # LOCATION_ALT_MAX_M
ARDUPILOT_NAN_PARAMS = {mavlink.MAV_CMD_NAV_WAYPOINT: {4}, mavlink.MAV_CMD_NAV_LAND: {4},
                        mavlink.MAV_CMD_NAV_TAKEOFF: {4}, mavlink.MAV_CMD_NAV_VTOL_TAKEOFF: {4},
                        mavlink.MAV_CMD_NAV_VTOL_LAND: {3, 4}}
INVALID_PARAMS = (mavlink.MAV_MISSION_INVALID_PARAM1, mavlink.MAV_MISSION_INVALID_PARAM2,
                  mavlink.MAV_MISSION_INVALID_PARAM3, mavlink.MAV_MISSION_INVALID_PARAM4)


def _latlon_valid(item: WireItem) -> bool:
    return abs(item.x) <= 900_000_000 and abs(item.y) <= 1_800_000_000


def ardupilot_item_result(item: WireItem, count: int) -> int:
    """The MAV_MISSION_RESULT ArduCopter gives a mission or rally item of an upload of `count` items for
    what it cannot store (see above); ACCEPTED leaves the rest of the checks to the caller."""
    if item.mission_type == MissionType.MISSION:
        nan_ok = ARDUPILOT_NAN_PARAMS.get(item.command, set())
        for number, value in enumerate((item.param1, item.param2, item.param3, item.param4), start=1):
            if math.isinf(value) or (math.isnan(value) and number not in nan_ok):
                return INVALID_PARAMS[number - 1]
    if item.mission_type == MissionType.RALLY or is_positional(item.command):
        if abs(item.x) > 900_000_000:
            return mavlink.MAV_MISSION_INVALID_PARAM5_X
        if abs(item.y) > 1_800_000_000:
            return mavlink.MAV_MISSION_INVALID_PARAM6_Y
        if math.isnan(item.z) or abs(item.z) >= ARDUPILOT_ALT_MAX_M:
            return mavlink.MAV_MISSION_INVALID_PARAM7
    if item.mission_type == MissionType.MISSION and item.command == mavlink.MAV_CMD_DO_JUMP:
        # The target is a uint16 on board: a C float-to-integer conversion, whose low 16 bits it keeps.
        target = (int(item.param1) & 0xFFFF) if abs(item.param1) < 2**31 else 0
        if target == 0 or target >= count:
            return mavlink.MAV_MISSION_ERROR
    return mavlink.MAV_MISSION_ACCEPTED


def _next_nav(items: list[WireItem], index: int, count: int = 3) -> list[tuple[object, ...]]:
    """The next `count` navigation items from `index` on, as ArduPilot's AP_Mission_ChangeDetector
    compares them (a change in them while in AUTO restarts the current item)."""
    nav = [it for it in items[index:] if it.command <= mavlink.MAV_CMD_NAV_LAST]
    return [(it.command, it.frame, it.param1, it.param2, it.param3, it.param4, it.x, it.y, it.z) for it in nav[:count]]

