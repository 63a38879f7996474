"""One followed vehicle's messages: into its record as they come, and as events where someone acts on them.

Every GLOBAL_POSITION_INT, MISSION_CURRENT, MISSION_ITEM_REACHED and gimbal report (GIMBAL_DEVICE_ATTITUDE_STATUS,
MOUNT_ORIENTATION, MOUNT_STATUS: where the camera points) goes into the drone's record (and
through it into the journal); its photo reports (ArduPilot's CAMERA_FEEDBACK, PX4's
CAMERA_IMAGE_CAPTURED), mode / arming / landed-state changes and STATUSTEXT lines are published as
events (events.PhotoTaken, ModeChanged, ArmingChanged, LandedStateChanged, VehicleSaid), and a mode
nobody in this run asked for, mid-mission, as LeftMission. Owned by the drone's follower thread
(drone_flight.DroneFlight): the session hands it each message of its vehicle once recording started.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from missionplan.bridge.formats.gimbal import quaternion_pitch_roll
from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.link.camera_check import CAMERA_COMPONENTS
from missionplan.bridge.link.readiness import VehicleState, is_autopilot_heartbeat
from missionplan.bridge.transfer.onboard_log import euler_degrees

from .events import (ArmingChanged, FlightEvent, LandedStateChanged, LeftMission, ModeChanged, PhotoTaken,
                     VehicleSaid)
from .record import DroneRecord

CAPTURE_OK = 1  # CAMERA_IMAGE_CAPTURED capture_result (a flag, not an enum): 1 success
ON_GROUND_M = 0.3      # relative altitude under which a disarmed vehicle counts as landed
# Modes a mission flies in (ArduPilot AUTO; PX4 AUTO.MISSION, and AUTO.TAKEOFF), and the modes of its
# final return (PX4 switches to AUTO.RTL / AUTO.LAND for a mission's final RTL / LAND item; ArduPilot
# flies it in AUTO).
MISSION_MODES = {Flavour.ARDUPILOT: {"AUTO"}, Flavour.PX4: {"MISSION", "TAKEOFF"}}
RETURN_MODES = {"RTL", "LAND", "SMART_RTL"}
# Words of a STATUSTEXT that a crew must hear at once (a failsafe, a fence, the EKF, a crash).
ALERT_WORDS = ("failsafe", "fence", "ekf", "crash", "battery", "low bat", "critical", "emergency", "lost")
# ...said with a severity of WARNING or worse (MAV_SEVERITY 0-4): ArduCopter says "EKF3 IMU0 MAG0 in-flight
# yaw alignment complete" at INFO on every take-off, which is no alert and no reason a flight ended.
ALERT_SEVERITY = mavlink.MAV_SEVERITY_WARNING


class TelemetryRecorder:
    """One vehicle's messages into its record and its events (see the module docstring)."""

    def __init__(self, record: DroneRecord, state: VehicleState, commanded: set[str],
                 publish: Callable[[FlightEvent], None], bar: Any = None, camera_records: bool = False) -> None:
        """commanded: the modes this run commanded that are no departure from the mission (the vehicle
        session's action.commanded). camera_records (plan --capture camera, camera-interval): the photos are
        the MAVLink camera's own CAMERA_IMAGE_CAPTURED (a camera component's, capture_result 1; a failed
        capture counted apart), not the autopilot's CAMERA_FEEDBACK nor PX4's own CAMERA_IMAGE_CAPTURED."""
        self.camera_records = camera_records
        self.record, self.state, self.commanded, self.publish, self.bar = record, state, commanded, publish, bar
        self.sysid = record.id
        self.armed, self.rel_alt, self.last_reached = True, 0.0, -1  # as last reported
        self.recording = False  # from the mission start on: what came before is not this flight
        self.camera_component: int | None = None  # who sends this vehicle's CAMERA_IMAGE_CAPTURED: the first heard
        self.said: tuple[Any, ...] = (None, None, None, 0)  # mode, armed, landed state, STATUSTEXT count already said
        self.severity: dict[str, int] = {}  # STATUSTEXT text -> its MAV_SEVERITY, as last heard
        self.left_mission: str = ""  # the mode someone else switched it to mid-mission
        self.warnings: list[str] = []  # what the vehicle said that a crew must hear (failsafes...)
        self.mission_heard_at = 0.0  # our monotonic clock: the latest MISSION_CURRENT

    def start(self) -> None:
        """Record from now on (the mission start, or a re-attach): what the vehicle said before is not said."""
        self.said = (None, None, None, self.state.texts_total)
        self.recording = True

    def take_if_started(self, msg: Any) -> None:
        if self.recording:
            self.take(msg)

    def take(self, msg: Any) -> None:
        """Record one message of our vehicle."""
        rec = self.record
        t = rec.last_heard = time.time()
        kind = msg.get_type()
        if kind == "STATUSTEXT":  # a chunked text is keyed by its last chunk: close enough for its severity
            self.severity[str(msg.text).strip()] = int(msg.severity)
        if kind in ("HEARTBEAT", "EXTENDED_SYS_STATE", "STATUSTEXT"):
            self._note_changes(t)
        if kind == "GLOBAL_POSITION_INT":
            self.rel_alt = msg.relative_alt / 1000.0
            lat, lon = msg.lat / 1e7, msg.lon / 1e7
            rec.add_sample((t, lat, lon, self.rel_alt, float(np.hypot(msg.vx, msg.vy)) / 100.0,
                            msg.time_boot_ms / 1000.0, -msg.vz / 100.0))
            if not rec.last_position or t - rec.last_position[3] >= 1.0:  # journaled once a second
                rec.set(last_position=[lat, lon, self.rel_alt, t])
        elif kind == "HEARTBEAT" and is_autopilot_heartbeat(msg):  # not a camera's beside it (base_mode 0)
            self.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        elif kind == "MISSION_CURRENT":
            self.mission_current(msg)
            if self.bar is not None:
                self.bar.n = min(max(rec.current, self.bar.n), self.bar.total)
                self.bar.refresh()
        elif kind == "MISSION_ITEM_REACHED":
            rec.add_reached(t, int(msg.seq))
            self.last_reached = max(self.last_reached, int(msg.seq))
        elif kind == "CAMERA_FEEDBACK" and not self.camera_records:
            self.publish(PhotoTaken(self.sysid, t, int(msg.img_idx), msg.lat / 1e7, msg.lng / 1e7, float(msg.alt_rel),
                                    attitude=(float(msg.roll), float(msg.pitch), float(msg.yaw)),
                                    amsl_m=float(msg.alt_msl)))
            rec.set(captures=max(rec.captures, int(msg.completed_captures), int(msg.img_idx) + 1))
        elif kind == "CAMERA_IMAGE_CAPTURED" and self.camera_records:
            self._camera_record(msg, t)
        elif kind == "GIMBAL_DEVICE_ATTITUDE_STATUS":  # the camera gimbal (ArduPilot's mount, PX4's gimbal)
            angles = quaternion_pitch_roll(list(msg.q))
            if angles is not None:
                rec.add_gimbal(t, *angles)
        elif kind == "MOUNT_ORIENTATION":  # PX4's older report of the same (degrees)
            rec.add_gimbal(t, float(msg.pitch), float(msg.roll))
        elif kind == "MOUNT_STATUS":  # ArduPilot's before the gimbal protocol v2: centidegrees, pitch then roll
            rec.add_gimbal(t, msg.pointing_a / 100.0, msg.pointing_b / 100.0)
        elif kind == "CAMERA_IMAGE_CAPTURED":
            # PX4's photo report (its camera_feedback module, one per trigger, image_index from 0 after
            # boot), or a MAVLink camera's: from one component only, their indices are separate counts.
            if self.camera_component is None:
                self.camera_component = msg.get_srcComponent()
            index = int(msg.image_index)
            if msg.get_srcComponent() == self.camera_component and index >= 0:
                if int(msg.capture_result) == CAPTURE_OK:
                    self.publish(PhotoTaken(self.sysid, t, index, msg.lat / 1e7, msg.lon / 1e7, self.rel_alt,
                                            attitude=euler_degrees(list(msg.q)), amsl_m=msg.alt / 1000.0))
                rec.set(captures=max(rec.captures, index + 1))

    def _camera_record(self, msg: Any, t: float) -> None:
        """A MAVLink camera's CAMERA_IMAGE_CAPTURED: from the first camera component heard (never the autopilot's
        own, PX4 sends those too), the camera's image_index and file_url kept; capture_result 1 only is a photo."""
        component = msg.get_srcComponent()
        if component not in CAMERA_COMPONENTS:
            return
        if self.camera_component is None:
            self.camera_component = component
        index = int(msg.image_index)
        if component != self.camera_component or index < 0:
            return
        rec = self.record
        if int(msg.capture_result) != CAPTURE_OK:
            if index not in rec.failed_indices:
                rec.failed_indices.add(index)
                rec.set(failed_captures=len(rec.failed_indices))
        else:
            url = str(getattr(msg, "file_url", "") or "").rstrip("\x00")
            self.publish(PhotoTaken(self.sysid, t, index, msg.lat / 1e7, msg.lon / 1e7, msg.relative_alt / 1000.0,
                                    attitude=euler_degrees(list(msg.q)), amsl_m=msg.alt / 1000.0, file_url=url))
        rec.set(captures=max(rec.captures, index + 1))

    def mission_current(self, msg: Any) -> None:
        """MISSION_CURRENT: where in its mission the vehicle is, and in which state."""
        self.mission_heard_at = time.monotonic()
        self.record.set(current=int(msg.seq), mission_state=int(getattr(msg, "mission_state", 0) or 0))

    def _note_changes(self, t: float) -> None:
        """Mode, arming and landed-state changes and new STATUSTEXT lines, published as events; the
        STATUSTEXT lines a crew must hear at once marked as warnings."""
        state = self.state
        mode, armed, landed, texts = self.said
        if state.custom_mode is not None and state.mode_name() != mode:
            self.publish(ModeChanged(self.sysid, t, state.mode_name(), state.in_auto))
            self._mode_changed(state.mode_name(), mode)
        if state.armed is not None and state.armed != armed:
            self.publish(ArmingChanged(self.sysid, t, state.armed))
        if state.landed_state is not None and state.landed_state != landed:
            self.publish(LandedStateChanged(self.sysid, t, state.landed_state))
        fresh = min(state.texts_total - texts, len(state.texts))
        for text in state.texts[len(state.texts) - fresh:]:
            warning = (any(word in text.lower() for word in ALERT_WORDS)
                       and self.severity.get(text, ALERT_SEVERITY) <= ALERT_SEVERITY)
            if warning:
                self.warnings.append(text)
            self.publish(VehicleSaid(self.sysid, t, text, warning))
        self.said = (state.mode_name() if state.custom_mode is not None else None, state.armed,
                     state.landed_state, state.texts_total)

    def _mode_changed(self, new: str, old: str | None) -> None:
        """A mode nobody in this run asked for, mid-mission: RC, another ground station, a failsafe."""
        if old is None or new in MISSION_MODES[self.state.flavour] or new in self.commanded:
            return
        rec = self.record
        last_seq = len(rec.wire) - 1
        if new in RETURN_MODES and self.at_final_return(last_seq):
            return  # PX4 flies a mission's final RTL / LAND item in its own mode
        if not self.armed and self.disarmed_on_ground():
            return  # after landing
        self.left_mission = new
        self.publish(LeftMission(self.sysid, time.time(), new, time.monotonic(), rec.current, last_seq))

    def disarmed_on_ground(self) -> bool:
        on_ground = self.state.on_ground  # PX4's landed state: its altitude drifts on the ground
        return not self.armed and (on_ground if on_ground is not None else self.rel_alt < ON_GROUND_M)

    def at_final_return(self, last_seq: int) -> bool:
        """At the mission's last item, an RTL or a LAND: PX4 reports no MISSION_ITEM_REACHED for it
        (nor a mission_state), it lands and disarms there."""
        rec = self.record
        if not (0 <= last_seq < len(rec.wire)
                and int(rec.wire[last_seq].command) in (mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
                                                        mavlink.MAV_CMD_NAV_LAND)):
            return False
        # At it, or only DO_ items left before it (PX4 may switch to RTL while it still reports the
        # DO_SET_CAM_TRIGG_DIST after the last waypoint as its current item).
        return all(int(item.command) > mavlink.MAV_CMD_NAV_LAST for item in rec.wire[max(rec.current, 0) + 1:last_seq])

    def mission_complete(self, last_seq: int) -> bool:
        """Its mission done, by its own word: complete, its last item reached, or at its final return."""
        return (self.record.mission_state == mavlink.MISSION_STATE_COMPLETE or self.last_reached >= last_seq
                or self.at_final_return(last_seq))
