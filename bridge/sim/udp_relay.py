"""A loopback relay between vehicles and a ground station (UdpRelay): it breaks the link on purpose and watches what
crosses it.

Put between a fleet of SITL vehicles and `fly` (the flight-fault tests, `missionplan verify --sim sitl`), the relay is
the ground truth of what the ground station sent and of what the vehicles did, whatever `fly` says: their armed
flag, mode, mission item (MISSION_CURRENT) and the items they reached (MISSION_ITEM_REACHED), their photos, their
clock, and the battery they used (BATTERY_STATUS current_consumed, or SYS_STATUS current integrated over their clock),
all read from what the vehicles send, dropped or not.
"""

from __future__ import annotations

import socket
import time

RELAY_BUFFER = 4 << 20  # bytes asked for each relay socket's receive buffer (the kernel may give less)


def _one_log_data(data: bytes, log_data_id: int) -> bool:
    """Whether a datagram is exactly one MAVLink 2 LOG_DATA message (unsigned or signed), whose id is
    log_data_id."""
    if len(data) < 12 or data[0] != 0xFD or int.from_bytes(data[7:10], "little") != log_data_id:
        return False
    size = 12 + data[1] + (13 if data[2] & 1 else 0)
    return len(data) == size


class UdpRelay:
    """A loopback relay between vehicles and a ground station, to break the link on purpose.

    Vehicles send to `vehicle_port` (their udpclient / GCS link points there); the relay forwards each
    vehicle's packets to the ground station at `gcs_port` from a socket of its own per vehicle address
    (so the ground station still sees every vehicle at its own address, as over radios), and the ground
    station's answers back to that vehicle. `drop()` loses everything in both directions until
    `restore()`. What the ground station sends is parsed and kept per vehicle address (`sent`: message
    types in order), so a test can show what was, or was not, commanded; what the vehicles send is
    parsed too, for their latest state (`state(sysid)`: armed, custom mode, mission item, the highest
    CAMERA_FEEDBACK img_idx, how often it armed, when it last disarmed), dropped or not. `forget()`
    clears what the ground station sent (for a test that starts another ground station)."""

    def __init__(self, gcs_port: int) -> None:
        import threading

        from pymavlink.dialects.v20 import ardupilotmega as mavlink

        self.gcs = ("127.0.0.1", gcs_port)
        self.listen = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.listen.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RELAY_BUFFER)  # log downloads come in bursts
        self.listen.bind(("127.0.0.1", 0))
        self.vehicle_port = int(self.listen.getsockname()[1])
        self.dropping = False
        self.dropped = 0
        self.sent: dict[tuple[str, int], list[str]] = {}  # vehicle address -> message types the GCS sent it
        self._parsers: dict[tuple[str, int], object] = {}
        self._vehicle_parsers: dict[tuple[str, int], object] = {}
        self._states: dict[int, dict[str, float]] = {}  # sysid -> armed, custom_mode, current, photos, ...
        self.photos_at: dict[int, dict[int, tuple[float, float]]] = {}  # sysid -> img_idx -> (lat, lon) it reported
        self._mavlink = mavlink
        self._sockets: dict[tuple[str, int], socket.socket] = {}  # vehicle address -> its socket toward the GCS
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="udp-relay", daemon=True)
        self._thread.start()

    def drop(self) -> None:
        self.dropping = True

    def restore(self) -> None:
        self.dropping = False

    def forget(self) -> None:
        """Forget what the ground station sent so far (commands_sent() starts again empty)."""
        self.sent = {}

    def commands_sent(self) -> list[str]:
        """Every message type the ground station sent to any vehicle but the harmless ones (heartbeats,
        stream and message requests), in order."""
        quiet = {"HEARTBEAT", "REQUEST_DATA_STREAM", "SYSTEM_TIME", "TIMESYNC"}
        return [kind for kinds in self.sent.values() for kind in kinds if kind not in quiet]

    def _run(self) -> None:
        import select

        while not self._stop.is_set():
            readable, _, _ = select.select([self.listen, *self._sockets.values()], [], [], 0.1)
            for sock in readable:
                try:
                    data, source = sock.recvfrom(65536)
                except OSError:
                    continue
                if sock is self.listen:  # from a vehicle
                    # a log's bulk is nothing to watch (and parsing it is slow)
                    if not _one_log_data(data, self._mavlink.MAVLINK_MSG_ID_LOG_DATA):
                        self._watch(source, data)
                    out = self._sockets.get(source)
                    if out is None:
                        out = self._sockets[source] = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                        out.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RELAY_BUFFER)
                        out.bind(("127.0.0.1", 0))
                    if self.dropping:
                        self.dropped += 1
                    else:
                        try:
                            out.sendto(data, self.gcs)
                        except OSError:  # no ground station listening (yet, or any more): ICMP refused
                            pass
                    continue
                vehicle = next(addr for addr, s in self._sockets.items() if s is sock)  # from the GCS
                self._record(vehicle, data)
                if self.dropping:
                    self.dropped += 1
                else:
                    try:
                        self.listen.sendto(data, vehicle)
                    except OSError:  # the vehicle is gone (killed)
                        pass

    def state(self, sysid: int) -> dict[str, float]:
        """The vehicle's latest armed flag, custom mode and mission item, as it sent them; `photos`: the
        highest CAMERA_FEEDBACK img_idx; `arms`: how often it went from disarmed to armed; `disarmed_at`:
        our monotonic clock when it last went from armed to disarmed; `boot_s`: its clock (time since boot);
        `reached`: the highest MISSION_ITEM_REACHED seq; `consumed_mah`: BATTERY_STATUS's current_consumed;
        `current_a`: SYS_STATUS's current."""
        return dict(self._states.get(sysid, {}))

    def _watch(self, vehicle: tuple[str, int], data: bytes) -> None:
        parser = self._vehicle_parsers.get(vehicle)
        if parser is None:
            parser = self._vehicle_parsers[vehicle] = self._mavlink.MAVLink(None)
            parser.robust_parsing = True  # type: ignore[attr-defined]
        for msg in parser.parse_buffer(data) or []:  # type: ignore[attr-defined]
            kind, state = msg.get_type(), self._states.setdefault(msg.get_srcSystem(), {})
            if kind == "HEARTBEAT" and msg.type != self._mavlink.MAV_TYPE_GCS:
                armed = int(bool(msg.base_mode & self._mavlink.MAV_MODE_FLAG_SAFETY_ARMED))
                if state.get("armed") == 0 and armed:
                    state["arms"] = state.get("arms", 0) + 1
                elif state.get("armed") == 1 and not armed:
                    state["disarmed_at"] = time.monotonic()
                state["armed"], state["custom_mode"] = armed, int(msg.custom_mode)
            elif kind == "MISSION_CURRENT":
                state["current"] = int(msg.seq)
            elif kind == "MISSION_ITEM_REACHED":
                state["reached"] = max(state.get("reached", -1), int(msg.seq))
            elif kind == "BATTERY_STATUS" and int(msg.id) == 0 and int(msg.current_consumed) >= 0:
                state["consumed_mah"] = float(msg.current_consumed)
            elif kind == "SYS_STATUS" and int(msg.current_battery) >= 0:
                self._integrate_current(state, int(msg.current_battery) / 100.0)
            elif kind == "CAMERA_FEEDBACK":
                state["photos"] = max(state.get("photos", 0), int(msg.img_idx))
                self.photos_at.setdefault(msg.get_srcSystem(), {})[int(msg.img_idx)] = (msg.lat / 1e7, msg.lng / 1e7)
            elif kind in ("GLOBAL_POSITION_INT", "SYSTEM_TIME"):
                state["boot_s"] = int(msg.time_boot_ms) / 1000.0

    @staticmethod
    def _integrate_current(state: dict[str, float], amps: float) -> None:
        """SYS_STATUS's current (A), summed over the vehicle's own clock into `integrated_mah` (from its last boot)."""
        now = state.get("boot_s")
        last = state.get("current_at_s")
        if now is not None and last is not None and now < last:  # it rebooted: its battery counts from zero again
            state["integrated_mah"] = 0.0
        elif now is not None and last is not None:
            state["integrated_mah"] = state.get("integrated_mah", 0.0) + state.get("current_a", 0.0) * (now - last) / 3.6
        state["current_a"] = amps
        if now is not None:
            state["current_at_s"] = now

    def used_mah(self, sysid: int) -> float | None:
        """What the vehicle's battery gave since its boot, as it said last: BATTERY_STATUS's current_consumed, else
        SYS_STATUS's current summed over its clock; None if it said neither."""
        state = self._states.get(sysid, {})
        if "consumed_mah" in state:
            return float(state["consumed_mah"])
        return float(state["integrated_mah"]) if "integrated_mah" in state else None

    def _record(self, vehicle: tuple[str, int], data: bytes) -> None:
        parser = self._parsers.get(vehicle)
        if parser is None:
            parser = self._parsers[vehicle] = self._mavlink.MAVLink(None)
            parser.robust_parsing = True  # type: ignore[attr-defined]
        for msg in parser.parse_buffer(data) or []:  # type: ignore[attr-defined]
            kind = msg.get_type()
            if kind in ("COMMAND_LONG", "COMMAND_INT"):
                kind = f"{kind} {int(msg.command)}"
            self.sent.setdefault(vehicle, []).append(kind)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        for sock in [self.listen, *self._sockets.values()]:
            sock.close()

    def __enter__(self) -> UdpRelay:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
