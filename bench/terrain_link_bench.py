"""The terrain an ArduCopter takes from the ground station for a 1 km x 1 km area: blocks, bytes and time.

Run by hand: `.venv/bin/python bench/terrain_link_bench.py [--spacings 100,30] [--side 1000] [--write-doc FILE]`.
For each TERRAIN_SPACING a fresh ArduCopter SITL (../shared/sitl/arducopter, speed-up 10, no terrain files) is
set to that spacing and served a sloping ground (a plain function, no DEM file) by
missionplan.bridge.session.terrain's TerrainServer over TCP loopback, with TERRAIN_CHECK on a 250 m lattice over
a square area of `side` metres centred on its home, until it reports no block pending and ground at every
point (wait_terrain_loaded). The table gives the spacing its TERRAIN_REPORT then says, the TERRAIN_REQUESTs
answered, the TERRAIN_DATA blocks sent and those it holds at the end (its cache keeps TERRAIN_CACHE_SZ grids of
56), their bytes (MAVLink 2, unsigned), the wall time over loopback and the vehicle's own seconds (SYSTEM_TIME
before and after; it asks for one grid per 2 s of its clock), and the time those bytes take on a 57,600 baud
telemetry radio, computed (10 bits a byte: start, 8 data, stop; the radio's own framing and the vehicle's
requests and reports going the other way not counted). No assertions: a measurement, not a test.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from missionplan.bridge.link.connection import Link
from missionplan.bridge.link.params import ParamClient
from missionplan.bridge.session.terrain import TerrainServer, wait_terrain_loaded
from missionplan.bridge.session.vehicle_session import VehicleSession
from missionplan.bridge.transfer.protocol import Timeouts
from missionplan.testing.arducopter import SPEEDUP, ArduCopter, boot_ms, sitl_or_skip

import doctable  # bench/doctable.py: --write-doc

HOME = (44.4056, 8.9463, 150.0, 0.0)  # Genoa
M_PER_DEG = 111_320.0
LATTICE_M = 250.0
RADIO_BAUD = 57_600
BITS_PER_BYTE = 10  # 8N1 on the serial line
LOAD_S = 180.0


def slope(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """150 m at home, rising 5 m per 100 m east and 2 m per 100 m north."""
    north = (np.asarray(lat) - HOME[0]) * M_PER_DEG
    east = (np.asarray(lon) - HOME[1]) * M_PER_DEG * math.cos(math.radians(HOME[0]))
    return HOME[2] + 0.05 * east + 0.02 * north


def area_points(side_m: float) -> list[tuple[float, float]]:
    """A LATTICE_M lattice over the square of side_m metres centred on home, edges included."""
    steps = np.linspace(-side_m / 2, side_m / 2, int(round(side_m / LATTICE_M)) + 1)
    dlat, dlon = M_PER_DEG, M_PER_DEG * math.cos(math.radians(HOME[0]))
    return [(HOME[0] + n / dlat, HOME[1] + e / dlon) for n in steps for e in steps]


def load_once(spacing: int, side_m: float) -> dict[str, float]:
    with ArduCopter(sysid=1, home=HOME) as sitl, Link(sitl.url) as link:
        session = VehicleSession.open(link, 1, 30.0, Timeouts())
        ParamClient(link, session.backend.vehicle).set("TERRAIN_SPACING", float(spacing))
        server = TerrainServer(slope)
        vehicle_before = boot_ms(link, 1, time.monotonic() + 5.0)
        started = time.monotonic()
        status = wait_terrain_loaded(session, server, started + LOAD_S, area_points(side_m))
        wall_s = time.monotonic() - started
        vehicle_after = boot_ms(link, 1, time.monotonic() + 5.0)
        if not status.loaded_ok:
            raise SystemExit(f"spacing {spacing} m: {status.line()}")
        served = server.served()
        vehicle_s = math.nan if vehicle_before is None or vehicle_after is None else (
            (vehicle_after - vehicle_before) / 1000.0)
        session.close()
        return {"requests": served.requests, "blocks": served.blocks_sent, "bytes": served.bytes_sent,
                "loaded": status.loaded or 0, "reported_spacing": status.own.spacing if status.own else 0,
                "wall_s": wall_s, "vehicle_s": vehicle_s,
                "radio_s": served.bytes_sent * BITS_PER_BYTE / RADIO_BAUD}


def table(args: argparse.Namespace) -> int:
    side = args.side
    print(f"terrain for a {side / 1000:g} km x {side / 1000:g} km area around home, ArduCopter SITL "
          f"(speed-up {SPEEDUP}), TCP loopback")
    print(f"{'spacing m':>9} {'reported':>8} {'requests':>8} {'blocks':>7} {'loaded':>7} {'bytes':>7} {'wall s':>7} "
          f"{'vehicle s':>9} {'57.6 kbaud s':>12}")
    for text in args.spacings.split(","):
        spacing = int(text)
        r = load_once(spacing, side)
        print(f"{spacing:>9} {r['reported_spacing']:>8.0f} {r['requests']:>8.0f} {r['blocks']:>7.0f} "
              f"{r['loaded']:>7.0f} {r['bytes']:>7.0f} {r['wall_s']:>7.1f} {r['vehicle_s']:>9.1f} "
              f"{r['radio_s']:>12.1f}", flush=True)
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacings", default="100,30", help="TERRAIN_SPACING values, metres, comma-separated")
    parser.add_argument("--side", type=float, default=1000.0, help="the area's side, metres")
    doctable.add_option(parser)
    args = parser.parse_args()
    try:
        sitl_or_skip()
    except BaseException as err:  # pytest's Skipped outside pytest: say why and stop
        print(err)
        return 1
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


if __name__ == "__main__":
    raise SystemExit(main())
