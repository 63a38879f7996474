"""The ground-station side of the MAVLink mission protocol over a pymavlink Link.

Owns upload (MISSION_COUNT -> MISSION_REQUEST_INT / legacy MISSION_REQUEST -> MISSION_ITEM_INT ->
MISSION_ACK), download (MISSION_REQUEST_LIST -> MISSION_COUNT -> MISSION_REQUEST_INT ->
MISSION_ITEM_INT -> MISSION_ACK), clear-all and set-current, for every mission_type, addressed to one
system and component and deaf to every other one on the link.

Time-outs and retries: each side re-sends its last message when the answer does not come. In a
download we drive, and the re-send interval adapts to the measured round trip (like TCP's
retransmission timer: four times the smoothed round trip, at least `min_retry`, at most
`item_timeout`, the 1.5 s QGroundControl uses). In an upload the vehicle drives and re-requests by
itself (ArduPilot after 1 s, PX4 after 0.25 s): any request, in order, out of order or repeated, is
answered with that item, and we re-send on our own only after `item_timeout` of silence, so we never
race the vehicle's re-request (ArduPilot answers an item it did not ask for with INVALID_SEQUENCE, and
one after the end with ERROR). The upload succeeds only at a MISSION_ACK ACCEPTED after the last item
was asked for; an ERROR or INVALID_SEQUENCE ack that arrives just after it is a stray, not a failure.
A step gives up after `item_timeout * (retries + 1)` without progress. Every MAV_MISSION_RESULT has a
message.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import BridgeError
from ..link.connection import Link, VehicleInfo, mavlink
from ..formats.mission_items import MissionType, WireItem

ProgressFn = Callable[[int, int], None]  # (items done, items in all)

DENIED_TRIES, DENIED_WAIT_S = 5, 2.0  # another ground station's transfer: how long to wait it out
STRAY_ACK_S = 2.0  # after an upload, an ERROR / INVALID_SEQUENCE ack of its type is a late stray

RESULT_TEXT: dict[int, str] = {
    mavlink.MAV_MISSION_ACCEPTED: "accepted",
    mavlink.MAV_MISSION_ERROR: "generic error: the vehicle refused the mission (MAV_MISSION_ERROR)",
    mavlink.MAV_MISSION_UNSUPPORTED_FRAME:
        "an item uses a coordinate frame the vehicle does not support (MAV_MISSION_UNSUPPORTED_FRAME)",
    mavlink.MAV_MISSION_UNSUPPORTED:
        "an item uses a command or mission type the vehicle does not support (MAV_MISSION_UNSUPPORTED)",
    mavlink.MAV_MISSION_NO_SPACE: "the vehicle has no space for this many items (MAV_MISSION_NO_SPACE)",
    mavlink.MAV_MISSION_INVALID: "an item has an invalid parameter (MAV_MISSION_INVALID)",
    mavlink.MAV_MISSION_INVALID_PARAM1: "an item has an invalid param1 (MAV_MISSION_INVALID_PARAM1)",
    mavlink.MAV_MISSION_INVALID_PARAM2: "an item has an invalid param2 (MAV_MISSION_INVALID_PARAM2)",
    mavlink.MAV_MISSION_INVALID_PARAM3: "an item has an invalid param3 (MAV_MISSION_INVALID_PARAM3)",
    mavlink.MAV_MISSION_INVALID_PARAM4: "an item has an invalid param4 (MAV_MISSION_INVALID_PARAM4)",
    mavlink.MAV_MISSION_INVALID_PARAM5_X: "an item has an invalid x / latitude (MAV_MISSION_INVALID_PARAM5_X)",
    mavlink.MAV_MISSION_INVALID_PARAM6_Y: "an item has an invalid y / longitude (MAV_MISSION_INVALID_PARAM6_Y)",
    mavlink.MAV_MISSION_INVALID_PARAM7: "an item has an invalid z / altitude (MAV_MISSION_INVALID_PARAM7)",
    mavlink.MAV_MISSION_INVALID_SEQUENCE: "items arrived out of sequence (MAV_MISSION_INVALID_SEQUENCE)",
    mavlink.MAV_MISSION_DENIED:
        "the vehicle denied the operation, e.g. busy with another transfer or flying (MAV_MISSION_DENIED)",
    mavlink.MAV_MISSION_OPERATION_CANCELLED:
        "the operation was cancelled, e.g. the vehicle timed out waiting for items (MAV_MISSION_OPERATION_CANCELLED)",
}


def result_text(result: int) -> str:
    return RESULT_TEXT.get(result, f"unknown result {result}")


class MissionTransferError(BridgeError):
    """A mission transfer failed; result is the MAV_MISSION_RESULT when the vehicle sent one."""

    def __init__(self, message: str, result: int | None = None) -> None:
        super().__init__(message)
        self.result = result
        self.denied_at_start = False  # MAV_MISSION_DENIED before any item: busy with another transfer


class UploadUnconfirmed(MissionTransferError):
    """Every item went out, but the vehicle's final ACCEPTED was lost: a read-back decides."""


@dataclass
class Timeouts:
    """Protocol timing on the ground-station side."""

    item_timeout: float = 1.5  # longest wait before re-sending (QGroundControl's per-step time-out)
    retries: int = 5           # a step fails after item_timeout * (retries + 1) without progress
    min_retry: float = 0.01    # shortest re-send interval, whatever the round trip
    first_retry: float = 0.25  # re-send interval before any round trip was measured

    @property
    def step_limit(self) -> float:
        return self.item_timeout * (self.retries + 1)


class _RetryTimer:
    """Adaptive re-send interval from measured round trips (Karn: only first sends are timed)."""

    def __init__(self, timeouts: Timeouts) -> None:
        self.t = timeouts
        self.srtt: float | None = None

    def sample(self, rtt: float) -> None:
        self.srtt = rtt if self.srtt is None else 0.875 * self.srtt + 0.125 * rtt

    @property
    def interval(self) -> float:
        if self.srtt is None:
            return min(self.t.first_retry, self.t.item_timeout)
        return min(max(4.0 * self.srtt + 0.002, self.t.min_retry), self.t.item_timeout)


class MissionClient:
    """Mission protocol with one vehicle over a Link. Not thread-safe: one transfer at a time."""

    def __init__(self, link: Link, vehicle: VehicleInfo, timeouts: Timeouts | None = None) -> None:
        self.link = link
        self.vehicle = vehicle
        self.timeouts = timeouts or Timeouts()
        self.timer = _RetryTimer(self.timeouts)
        self.invalid_sequence_acks = 0  # ArduPilot's complaints about items it did not ask for
        self._stray_until: dict[int, float] = {}  # mission_type -> end of the stray-ACK window

    # ------------------------------------------------------------------------------------ helpers
    @property
    def _name(self) -> str:
        return f"vehicle {self.vehicle.sysid}"

    def _ours(self, msg: object) -> bool:
        """From our vehicle (system and component) and addressed to us or to everyone."""
        get_src = getattr(msg, "get_srcSystem", None)
        if get_src is None or get_src() != self.vehicle.sysid:
            return False
        if msg.get_srcComponent() != self.vehicle.compid:  # type: ignore[attr-defined]
            return False
        target = getattr(msg, "target_system", 0)
        # Addressed to our --gcs-sysid only: with another id than 255, replies meant for a second ground
        # station (MAVProxy at 255) on the same link are not ours.
        return target in (0, self.link.mav.srcSystem) if target else True

    def _recv(self, deadline: float) -> object | None:
        """Our vehicle's next message before deadline."""
        while True:
            msg = self.link.recv(deadline)
            if msg is None or self._ours(msg):
                return msg

    def _silence_hint(self) -> str:
        """': <why>' when MAVLink 2 signing explains the vehicle's silence (link.connection decides), else ''."""
        hint = self.link.signing_hint(self.vehicle.sysid)
        return f": {hint}" if hint else ""

    def _rebooted_since(self, start_reboots: int) -> bool:
        return self.link.reboots.get(self.vehicle.sysid, 0) > start_reboots

    def _ack(self, mission_type: int, result: int) -> None:
        self.link.mav.mission_ack_send(self.vehicle.sysid, self.vehicle.compid, result, mission_type)

    # ------------------------------------------------------------------------------------- upload
    def upload(self, mission_type: int, items: list[WireItem], progress: ProgressFn | None = None) -> None:
        """Upload items (seq 0..n-1). Returns at MISSION_ACK ACCEPTED, raises MissionTransferError otherwise.

        A vehicle busy with another ground station's transfer answers the count with MAV_MISSION_DENIED
        (ArduPilot denies a second uploader until the first is done or times out): that is tried again,
        DENIED_TRIES times over about DENIED_WAIT_S each, and then reported as such."""
        started = time.monotonic()
        for attempt in range(1, DENIED_TRIES + 1):
            try:
                return self._upload_once(mission_type, items, progress)
            except MissionTransferError as err:
                if not err.denied_at_start or attempt == DENIED_TRIES:
                    if err.denied_at_start:
                        raise MissionTransferError(
                            f"{self._name} denied the {MissionType(int(mission_type)).label} upload "
                            f"(MAV_MISSION_DENIED) {attempt} times over {time.monotonic() - started:.0f} s: another "
                            "ground station is probably transferring its mission (MAVProxy, QGroundControl); let its "
                            "transfer finish or close it, and if it uses this one's system and component id, give "
                            "this one another --gcs-sysid", err.result) from None
                    raise
            wait_until = time.monotonic() + DENIED_WAIT_S
            while self._recv(wait_until) is not None:  # the other transfer runs meanwhile
                pass
        raise AssertionError("unreachable")

    def _upload_once(self, mission_type: int, items: list[WireItem], progress: ProgressFn | None = None) -> None:
        mission_type = int(mission_type)
        label = MissionType(mission_type).label
        count = len(items)
        for index, item in enumerate(items):
            if item.seq != index or item.mission_type != mission_type:
                raise ValueError("upload items must have seq 0..n-1 and the upload's mission_type")
        mav, sysid, compid = self.link.mav, self.vehicle.sysid, self.vehicle.compid
        start_reboots = self.link.reboots.get(sysid, 0)
        step_limit = self.timeouts.step_limit

        def send_count() -> None:
            mav.mission_count_send(sysid, compid, count, mission_type)

        def send_item(seq: int) -> None:
            mav.mission_item_int_send(sysid, compid, **{**items[seq].fields(), "mission_type": mission_type})

        send_count()
        now = time.monotonic()
        last_progress = now
        last_heard = now  # the vehicle's last message of this transfer
        first_send: dict[int, float] = {}  # seq -> time first sent, for round-trip samples
        sent_seq = -1  # the last thing we sent: -1 is the count
        highest = -1
        requested_any = False
        nudge = self.timeouts.item_timeout
        while True:
            # The vehicle drives the upload and re-requests by itself (ArduPilot after 1 s, PX4 after
            # 0.25 s): we re-send only after a whole item_timeout of silence, never racing its re-request
            # (a copy it did not ask for earns an INVALID_SEQUENCE ack, and after the end an ERROR ack).
            deadline = min(last_heard + nudge, last_progress + step_limit)
            msg = self._recv(deadline)
            now = time.monotonic()
            if msg is None:
                if now - last_progress >= step_limit:
                    self._ack(mission_type, mavlink.MAV_MISSION_OPERATION_CANCELLED)  # let the vehicle stop waiting
                    if self._rebooted_since(start_reboots):
                        raise MissionTransferError(f"{self._name} rebooted during the {label} upload (after {highest + 1} "
                                                   f"of {count} items); the upload did not complete")
                    where = "answered nothing" if not requested_any else f"stopped asking after {highest + 1} of {count} items"
                    raise MissionTransferError(f"{self._name} {where} for {step_limit:g} s during the {label} upload; "
                                               f"the upload did not complete"
                                               f"{self._silence_hint() if not requested_any else ''}")
                if requested_any:
                    send_item(sent_seq)  # only for a vehicle that does not re-request by itself
                else:
                    send_count()
                last_heard = now
                continue
            kind = msg.get_type()
            if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
                if int(getattr(msg, "mission_type", 0)) != mission_type:
                    continue
                seq = int(msg.seq)
                if not 0 <= seq < count:
                    # A request from an earlier, longer transfer can arrive late; only a fresh one is an error.
                    continue
                last_heard = now
                if seq == sent_seq + 1 and sent_seq in first_send and seq not in first_send:
                    self.timer.sample(now - first_send[sent_seq])
                requested_any = True
                if seq > highest:
                    highest = seq
                    last_progress = now
                    if progress is not None:
                        progress(seq, count)
                first_send.setdefault(seq, now)
                send_item(seq)
                sent_seq = seq
            elif kind == "MISSION_ACK":
                if int(getattr(msg, "mission_type", 0)) != mission_type:
                    continue
                result = int(msg.type)
                if result == mavlink.MAV_MISSION_ACCEPTED:
                    if count == 0 or highest == count - 1:
                        self._stray_until[mission_type] = now + STRAY_ACK_S
                        if progress is not None:
                            progress(count, count)
                        return
                    continue  # a late ACCEPTED from an earlier transfer
                if result in (mavlink.MAV_MISSION_ERROR, mavlink.MAV_MISSION_INVALID_SEQUENCE) \
                        and self._stray(mission_type, now) and not requested_any:
                    continue  # the late answer to a stray copy of the previous upload's items
                if result == mavlink.MAV_MISSION_INVALID_SEQUENCE and requested_any:
                    self.invalid_sequence_acks += 1
                    continue  # ArduPilot's mid-upload complaint about a repeated item: not the end
                if self._rebooted_since(start_reboots):
                    raise MissionTransferError(f"{self._name} rebooted during the {label} upload (after {highest + 1} of "
                                               f"{count} items) and answered: {result_text(result)}; the upload did not "
                                               "complete", result)
                if result == mavlink.MAV_MISSION_ERROR and count > 0 and highest == count - 1:
                    # ArduPilot answers an item it no longer expects with ERROR: our copy of the last
                    # item came after it had completed, and its ACCEPTED was lost. Only a read-back tells,
                    # and more such ERRORs (a duplicate, an answer to a nudge) may still be on their way.
                    self._stray_until[mission_type] = now + STRAY_ACK_S
                    raise UploadUnconfirmed(f"{self._name} received every {label} item but its acknowledgement was "
                                            "lost; only a read-back can tell whether it holds the upload", result)
                if result == mavlink.MAV_MISSION_ERROR and requested_any:
                    raise MissionTransferError(f"{self._name} dropped the {label} upload after {highest + 1} of {count} "
                                               "items (MAV_MISSION_ERROR: it no longer knows this transfer; did it "
                                               "reboot?); the upload did not complete", result)
                error = MissionTransferError(f"{self._name} refused the {label} upload after {highest + 1} of {count} "
                                             f"items: {result_text(result)}", result)
                error.denied_at_start = result == mavlink.MAV_MISSION_DENIED and not requested_any
                raise error

    def _stray(self, mission_type: int, now: float) -> bool:
        """Within the window after an upload of this type in which stray error ACKs may still arrive."""
        return now < self._stray_until.get(mission_type, 0.0)

    # ----------------------------------------------------------------------------------- download
    def download(self, mission_type: int, progress: ProgressFn | None = None) -> list[WireItem]:
        """All items of one mission_type, in seq order."""
        mission_type = int(mission_type)
        label = MissionType(mission_type).label
        mav, sysid, compid = self.link.mav, self.vehicle.sysid, self.vehicle.compid
        step_limit = self.timeouts.step_limit

        def request_list() -> None:
            mav.mission_request_list_send(sysid, compid, mission_type)

        count = self._exchange(request_list, lambda m: m.get_type() == "MISSION_COUNT"
                               and int(getattr(m, "mission_type", 0)) == mission_type,
                               f"the {label} count", mission_type)
        total = int(count.count)  # type: ignore[attr-defined]
        items: list[WireItem] = []
        for seq in range(total):
            def request(seq: int = seq) -> None:
                mav.mission_request_int_send(sysid, compid, seq, mission_type)

            msg = self._exchange(request, lambda m, seq=seq: m.get_type() in ("MISSION_ITEM_INT", "MISSION_ITEM")
                                 and int(m.seq) == seq and int(getattr(m, "mission_type", 0)) == mission_type,
                                 f"{label} item {seq} of {total}", mission_type, step_limit)
            items.append(WireItem.from_message(msg))
            if progress is not None:
                progress(seq + 1, total)
        self._ack(mission_type, mavlink.MAV_MISSION_ACCEPTED)
        return items

    def _exchange(self, send: Callable[[], None], wanted: Callable[[object], bool], what: str,
                  mission_type: int, step_limit: float | None = None) -> object:
        """Send, re-send at the retry interval, until a wanted message comes; a MISSION_ACK error fails."""
        step_limit = self.timeouts.step_limit if step_limit is None else step_limit
        start = time.monotonic()
        send()
        first = True
        sent_at = start
        while True:
            msg = self._recv(min(sent_at + self.timer.interval, start + step_limit))
            now = time.monotonic()
            if msg is None:
                if now - start >= step_limit:
                    raise MissionTransferError(f"{self._name} did not send {what} within {step_limit:g} s"
                                               f"{self._silence_hint()}")
                send()
                first = False
                sent_at = now
                continue
            if wanted(msg):
                if first:
                    self.timer.sample(now - sent_at)
                return msg
            if msg.get_type() == "MISSION_ACK" and int(getattr(msg, "mission_type", 0)) == mission_type:
                result = int(msg.type)  # type: ignore[attr-defined]
                if result in (mavlink.MAV_MISSION_ERROR, mavlink.MAV_MISSION_INVALID_SEQUENCE) \
                        and self._stray(mission_type, now):
                    continue  # a late answer to a stray item of the upload that just completed
                if result not in (mavlink.MAV_MISSION_ACCEPTED, mavlink.MAV_MISSION_OPERATION_CANCELLED):
                    # OPERATION_CANCELLED can be a late answer to an earlier transfer; ACCEPTED likewise.
                    raise MissionTransferError(f"{self._name} refused to send {what}: {result_text(result)}", result)

    # -------------------------------------------------------------------------- clear, set current
    def clear(self, mission_type: int = MissionType.MISSION) -> None:
        """MISSION_CLEAR_ALL for one mission_type (or ALL) until the vehicle acknowledges it."""
        mission_type = int(mission_type)
        mav, sysid, compid = self.link.mav, self.vehicle.sysid, self.vehicle.compid

        def send() -> None:
            mav.mission_clear_all_send(sysid, compid, mission_type)

        msg = self._exchange(send, lambda m: m.get_type() == "MISSION_ACK"
                             and int(getattr(m, "mission_type", 0)) == mission_type,
                             f"an answer to clearing the {MissionType(mission_type).label}", -1)
        result = int(msg.type)  # type: ignore[attr-defined]
        if result != mavlink.MAV_MISSION_ACCEPTED:
            raise MissionTransferError(f"{self._name} refused to clear the {MissionType(mission_type).label}: "
                                       f"{result_text(result)}", result)

    def set_current(self, seq: int) -> None:
        """Make item seq the current one (MISSION_SET_CURRENT) and wait until MISSION_CURRENT says so."""
        mav, sysid, compid = self.link.mav, self.vehicle.sysid, self.vehicle.compid

        def send() -> None:
            mav.mission_set_current_send(sysid, compid, seq)

        self._exchange(send, lambda m: m.get_type() == "MISSION_CURRENT" and int(m.seq) == seq,
                       f"MISSION_CURRENT {seq}", MissionType.MISSION)


__all__ = ["MissionClient", "MissionTransferError", "UploadUnconfirmed", "Timeouts", "result_text", "RESULT_TEXT"]
