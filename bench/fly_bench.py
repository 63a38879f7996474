"""Plan, upload and fly shipped maps against in-process mock autopilots; print one row per flight.

Run by hand: `.venv/bin/python bench/fly_bench.py [--maps leonardo,grid-city] [--uavs 3,5,6] [--policy nn]`.
Each row: the flown coverage (our rule, and the stricter whole-cell rule), the closest approach of two
drones against the plan's promise, simulated flight time against the plan's, photos, and wall time
of the flight (upload, verify, fly, judge) at the speed-up used.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from missionplan.cli import main  # noqa: E402
from missionplan.fly import fly, start_mock_fleet  # noqa: E402

SPEEDUP = {"leonardo": 2.0}  # a 20 x 10 m arena; the street maps are hundreds of metres: 50x
DEFAULT_SPEEDUP = 50.0
TELEMETRY_HZ = 50.0


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", default="leonardo,grid-city,old-town,river-city")
    parser.add_argument("--uavs", default="3,5,6")
    parser.add_argument("--policy", default="nn", choices=("nn", "expert"))
    args = parser.parse_args()
    header = (f"{'map':<11}{'A':>3}{'targets':>9}{'cover %':>9}{'whole %':>9}{'sep 3d m':>10}{'promised':>10}"
              f"{'tol m':>7}{'flight s':>10}{'planned':>9}{'photos':>8}{'wall s':>8}{'speed-up':>9}")
    print(header)
    print("-" * len(header))
    for name in args.maps.split(","):
        for uavs in (int(u) for u in args.uavs.split(",")):
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp)
                with contextlib.redirect_stdout(io.StringIO()):  # the table only
                    status = main(["plan", "--map", name, "--uavs", str(uavs), "--policy", args.policy,
                                   "--out", str(out), "--quiet"])
                if status != 0:
                    print(f"{name:<11}{uavs:>3}  plan failed")
                    continue
                speedup = SPEEDUP.get(name, DEFAULT_SPEEDUP)
                mock = start_mock_fleet(out, speedup)
                start = time.monotonic()
                try:
                    result = fly(out, mock.client_url, timeout_s=900, progress=False, time_scale=speedup,
                                 telemetry_hz=TELEMETRY_HZ)
                finally:
                    mock.stop()
                wall = time.monotonic() - start
                doc = json.loads((out / "flight.json").read_text())
                sep = doc["min_separation_m"]
                flight = max(d["flight_s"] for d in doc["drones"])
                planned = max(d["planned_flight_s"] for d in doc["drones"])
                photos = sum(d["photos"] for d in doc["drones"])
                note = "" if not result.problems else "  " + "; ".join(result.problems)
                print(f"{name:<11}{uavs:>3}{doc['targets']:>9}{doc['coverage']:>9.2f}"
                      f"{doc['coverage_other_rules']['whole_cell']:>9.2f}{sep['3d']:>10.2f}{sep['planned_3d']:>10.2f}"
                      f"{sep['tolerance']:>7.2f}{flight:>10.1f}{planned:>9.1f}{photos:>8}{wall:>8.1f}{speedup:>8g}x"
                      f"{note}", flush=True)


if __name__ == "__main__":
    main_bench()
