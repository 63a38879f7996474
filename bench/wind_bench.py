"""ArduCopter SITL and the mock in wind, and with a GPS glitch: the numbers behind flight_models/wind.py,
sim/gps_glitch.py and docs/wind-model.md.

Run by hand: `.venv/bin/python bench/wind_bench.py [--winds 0,0,0 4,0,0 8,0,0] [--speed 10] [--no-sitl] [--no-mock]
[--glitch 4,20,0,15]`. Each wind is SPEED,FROM_DEG,TURBULENCE (SITL's SIM_WIND_SPD, _DIR, _TURB). One SITL
(--speedup 10) flies missionplan/testing/wind_flight.py's mission once per wind (take-off to 20 m, 6 s hover
above home, 150 m legs north, east, south, RTL west), then a mock (SITL-like, --speedup 20) flies the same;
per leg the table gives its time (item reached to item reached, vehicle clock), its ground speed along the leg
(middle half), its largest cross-track error and its mean SYS_STATUS current; then the hover current, the
battery used (SITL: BATTERY_STATUS current_consumed; mock: MockVehicle.consumed_mah) and the flight's time
(MISSION_START to the RTL item reached). --glitch SEQ,NORTH_M,EAST_M,SECONDS sets SIM_GPS1_GLTCH_X / _Y when
item SEQ becomes current and clears it SECONDS later (calm), and prints the texts and, each time it changes
by a metre, the reported (GLOBAL_POSITION_INT) and GPS_RAW_INT positions less the truth (SITL: SIMSTATE;
the mock: gps_glitch.true_position is not on the link, so the mock's line gives the reported track's jump).
No assertions: a measurement, not a test.
"""

from __future__ import annotations

import argparse
import bisect
import time

import doctable  # bench/doctable.py: --write-doc
from missionplan.bridge.sim.mock import MockAutopilot
from missionplan.testing.arducopter import ArduCopter, sitl_or_skip
from missionplan.testing.wind_flight import FlightRecord, fly_wind_mission

HOME = (45.4643, 9.1895, 120.0)
MOCK_SPEEDUP = 20.0


def _row(who: str, wind: tuple[float, float, float], rec: FlightRecord, wall: float) -> str:
    legs = " | ".join(f"{leg.time_s:.1f} s {leg.ground_speed:.2f} m/s {leg.cross_track_m:.1f} m {leg.current_a:.1f} A"
                      for leg in rec.legs)
    return (f"| {who} | {wind[0]:g} from {wind[1]:g}, turb {wind[2]:g} | {legs} | {rec.hover_current_a:.1f} A | "
            f"{rec.consumed_mah:.0f} mAh | {rec.flight_s:.1f} s | {wall:.0f} s |")


def _glitch_lines(rec: FlightRecord, start: float) -> list[str]:
    """Reported and GPS_RAW_INT positions less the truth, each time one of them changes by a metre."""
    out, last = [], None
    truth_t = [t for t, _, _ in rec.truth]
    gps_t = [t for t, _, _ in rec.gps]
    for t, n, e, _ in rec.track:
        if t < start or not rec.truth:
            continue
        _, tn, te = rec.truth[min(bisect.bisect_left(truth_t, t), len(truth_t) - 1)]
        _, gn, ge = rec.gps[min(bisect.bisect_left(gps_t, t), len(gps_t) - 1)]
        now = (round(n - tn), round(e - te), round(gn - tn), round(ge - te))
        if now != last:
            out.append(f"  t+{t - start:5.1f} s reported-truth {n - tn:6.1f} {e - te:6.1f}  gps-truth {gn - tn:6.1f} "
                       f"{ge - te:6.1f}")
            last = now
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--winds", nargs="*", default=["0,0,0", "4,0,0", "8,0,0"])
    parser.add_argument("--speed", type=float, default=10.0, help="WPNAV_SPEED (and the mock's cruise speed), m/s")
    parser.add_argument("--glitch", default="", help="SEQ,NORTH_M,EAST_M,SECONDS")
    parser.add_argument("--no-sitl", action="store_true")
    parser.add_argument("--no-mock", action="store_true")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        _measure(args)


def _measure(args: argparse.Namespace) -> None:
    winds = [tuple(float(x) for x in w.split(",")) for w in args.winds]
    glitch = tuple(float(x) for x in args.glitch.split(",")) if args.glitch else None
    flights = [(w, None) for w in winds] if glitch is None else [((0.0, 0.0, 0.0), glitch)]
    print("| autopilot | wind m/s | north (into) | east (across) | south (with) | home, west (across) | hover | used"
          " | flight | wall |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    params = {"WPNAV_SPEED": args.speed * 100.0}
    if not args.no_sitl:
        sitl_or_skip()
        with ArduCopter(sysid=1, home=(*HOME, 0.0), speedup=10) as vehicle:
            for wind, g in flights:
                t0 = time.monotonic()
                rec = fly_wind_mission(vehicle.url, 1, HOME, wind, timeout_s=300,  # type: ignore[arg-type]
                                       params=params, glitch=None if g is None else (int(g[0]), g[1], g[2], g[3]))
                print(_row("SITL", wind, rec, time.monotonic() - t0), flush=True)  # type: ignore[arg-type]
                if g is not None:
                    print("\n".join(f"  t={t:.1f} {text} (severity {sev})" for t, text, sev in rec.texts
                                    if "Arm" not in text))
                    print("\n".join(_glitch_lines(rec, rec.reached.get(int(g[0]) - 1, 0.0))))
    if not args.no_mock:
        for wind, g in flights:
            with MockAutopilot("udpin:127.0.0.1:0", sysids=[1], homes={1: HOME}, speedup=MOCK_SPEEDUP,
                               sitl_like=True, cruise_speed=args.speed) as mock:
                t0 = time.monotonic()
                rec = fly_wind_mission(mock.client_url, 1, HOME, wind, stream_scale=1 / MOCK_SPEEDUP,  # type: ignore
                                       timeout_s=120, glitch=None if g is None else (int(g[0]), g[1], g[2], g[3]))
                rec.consumed_mah = mock.vehicle(1).consumed_mah
                print(_row("mock", wind, rec, time.monotonic() - t0), flush=True)  # type: ignore[arg-type]
                if g is not None:
                    print("\n".join(f"  t={t:.1f} {text}" for t, text, _ in rec.texts))
                    start = rec.reached.get(int(g[0]) - 1, 0.0)
                    jumps = [(round(t - start, 1), round(n), round(e)) for t, n, e, _ in rec.track if t >= start]
                    print("  reported track from the glitch:", jumps[:: max(len(jumps) // 40, 1)])


if __name__ == "__main__":
    main()
