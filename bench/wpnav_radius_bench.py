"""How close ArduCopter passes a corner waypoint, with its default WPNAV_RADIUS and with the plan's
acceptance radius written to it by the upload. Real ArduCopter SITL (../shared/sitl/arducopter).

Run by hand: `.venv/bin/python bench/wpnav_radius_bench.py [--radii default,0.5,0.06] [--leg 30] [--write-doc FILE]`.
For each row a fresh SITL: a mission of NAV_TAKEOFF to 10 m, a waypoint `leg` m north of home (the
corner), one `leg` m east of it (a right-angle turn), NAV_LAND there. `default` uploads with set_params off (the
copter keeps WPNAV_RADIUS = 200 cm); a number R uploads waypoints with param2 = R m, which the upload
turns into WPNAV_RADIUS = R * 100 cm. The vehicle is armed in GUIDED and started with
MAV_CMD_MISSION_START; the track (GLOBAL_POSITION_INT at 20 Hz of simulated time) is recorded until
the last waypoint is reached, and the table gives the closest horizontal approach to the corner and
the simulated seconds from the first position after MISSION_START (take-off) to the last waypoint.
No assertions: a measurement, not a test.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from missionplan.testing.arducopter import ArduCopter, sitl_or_skip

from missionplan.bridge.link.connection import mavlink
from missionplan.bridge.formats.mission_items import Mission, MissionItem
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.bridge.link.readiness import ARDUPILOT_GUIDED, mode_params
from missionplan.bridge.transfer.uploader import PymavlinkBackend, upload_plan

import doctable  # bench/doctable.py: --write-doc

ROOT = Path(__file__).resolve().parent.parent


HOME = (45.4643, 9.1895, 120.0, 0.0)
M_PER_DEG = 111_320.0


def _offset(north: float, east: float) -> tuple[float, float]:
    return HOME[0] + north / M_PER_DEG, HOME[1] + east / (M_PER_DEG * math.cos(math.radians(HOME[0])))


def _local(lat: float, lon: float) -> tuple[float, float]:
    return (lat - HOME[0]) * M_PER_DEG, (lon - HOME[1]) * M_PER_DEG * math.cos(math.radians(HOME[0]))


def _closest(track: list[tuple[float, float]], point: tuple[float, float]) -> float:
    """Closest distance from point to the polyline through the track (linear between samples)."""
    best = math.inf
    px, py = point
    for (ax, ay), (bx, by) in zip(track, track[1:]):
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((px - ax) * dx + (py - ay) * dy) / length2))
        best = min(best, math.hypot(ax + t * dx - px, ay + t * dy - py))
    return best


def fly_once(radius_m: float | None, leg: float, timeout: float = 180.0) -> dict[str, float]:
    corner = _offset(leg, 0.0)
    end = _offset(leg, leg)  # a right-angle turn at the corner
    param2 = radius_m or 0.0
    mission = Mission([MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=HOME[0],
                                   y=HOME[1], z=10.0),
                       MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=param2,
                                   x=corner[0], y=corner[1], z=10.0),
                       MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, param2=param2,
                                   x=end[0], y=end[1], z=10.0),
                       MissionItem(mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, x=end[0], y=end[1],
                                   z=0.0)], home=HOME[:3])
    with ArduCopter(sysid=1, home=HOME) as sitl, PymavlinkBackend(sitl.url, 1, timeouts=Timeouts(),
                                                                    connect_timeout=20) as b:
        report = upload_plan(b, [mission], set_params=radius_m is not None)
        wpnav = ParamClient(b.link, b.vehicle).get("WPNAV_RADIUS")  # what the copter will fly
        link = b.link
        deadline = time.monotonic() + timeout
        accepted = mavlink.MAV_RESULT_ACCEPTED
        link.command_long(1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, [mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 50_000],
                          deadline)  # 20 Hz (simulated time)
        while link.command_long(1, mavlink.MAV_CMD_DO_SET_MODE, mode_params(ARDUPILOT_GUIDED), deadline) != accepted:
            time.sleep(0.5)
        # refused until the EKF has a fix
        while link.command_long(1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1], deadline) != accepted:
            time.sleep(1.0)
            if time.monotonic() > deadline:
                raise RuntimeError("SITL never armed")
        if link.command_long(1, mavlink.MAV_CMD_MISSION_START, [0, 0], deadline) != accepted:
            raise RuntimeError("MISSION_START refused")
        track: list[tuple[float, float]] = []
        reached_last = False
        boot_ms: list[int] = []  # the vehicle's clock (simulated time) at each position
        while not reached_last and (msg := link.recv(deadline)) is not None:
            if msg.get_srcSystem() != 1:
                continue
            if msg.get_type() == "GLOBAL_POSITION_INT":
                track.append(_local(msg.lat / 1e7, msg.lon / 1e7))
                boot_ms.append(int(msg.time_boot_ms))
            elif msg.get_type() == "MISSION_ITEM_REACHED" and int(msg.seq) >= 3:
                reached_last = True
        if not reached_last:
            raise RuntimeError("the mission did not reach its last waypoint in time")
    return {"wpnav_cm": wpnav, "closest_m": _closest(track, (leg, 0.0)), "samples": len(track),
            "flight_s": (boot_ms[-1] - boot_ms[0]) / 1000.0, "set": bool(report.params)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--radii", default="default,0.5,0.06", help="'default' or metres, comma-separated")
    parser.add_argument("--leg", type=float, default=30.0, help="leg length, metres")
    doctable.add_option(parser)
    args = parser.parse_args()
    try:
        sitl_or_skip()
    except BaseException as err:  # pytest's Skipped outside pytest: say why and stop
        print(err)
        return 1
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


def table(args: argparse.Namespace) -> int:
    print(f"leg {args.leg:g} m, right-angle corner, 10 m altitude, WPNAV_SPEED default")
    print(f"{'plan radius':>12} {'WPNAV_RADIUS':>13} {'closest to corner m':>20} {'flight s':>9} {'samples':>8}")
    for text in args.radii.split(","):
        radius = None if text == "default" else float(text)
        r = fly_once(radius, args.leg)
        label = "default" if radius is None else f"{radius:g} m"
        print(f"{label:>12} {r['wpnav_cm']:>10.0f} cm {r['closest_m']:>20.2f} {r['flight_s']:>9.1f} {r['samples']:>8}",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
