"""What refusing a mission file beyond MAVLink's item count costs: memory and time, each case in a fresh child.

    python bench/limits_bench.py [--items 1000000]

Cases (files made in a temporary folder): a .waypoints of --items items (refused at line 65,537 while it is
read line by line), a .plan of 70,000 items (parsed, then refused for its count), a .plan over the 96 MiB
size bound (refused from its size, unread: a sparse file), and the largest compact .plan under the bound that
is still refused for its count (parsed first: the bound's price). Each row is the child's own peak resident
memory above what importing the reader took (VmHWM: bench/child_row.py), and the wall time of the read.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from child_row import peak_rss_mb, run_child_row

HOME = "0\t1\t0\t16\t0\t0\t0\t0\t45.07\t7.68\t240\t1\n"
ITEM = {"type": "SimpleItem", "command": 16, "frame": 3, "params": [0, 0, 0, None, 45.07, 7.68, 30],
        "autoContinue": True, "doJumpId": 1}


def write_waypoints(path: Path, items: int) -> None:
    with path.open("w") as out:
        out.write("QGC WPL 110\n" + HOME)
        out.writelines(f"{i}\t0\t3\t16\t0\t0\t0\t0\t45.07\t7.68\t30\t1\n" for i in range(1, items + 1))


def write_plan(path: Path, items: int) -> None:
    head = json.dumps({"fileType": "Plan", "version": 1, "mission": {"version": 2, "items": []}})
    one = json.dumps(ITEM, separators=(",", ":"))
    with path.open("w") as out:
        out.write(head[:head.index("[]") + 1])
        out.write(",".join([one] * items))
        out.write(head[head.index("[]") + 1:])


def child(path: str) -> None:
    """The child's row: read `path`, print its figures as one JSON line."""
    from missionplan.bridge import BridgeUsageError
    from missionplan.bridge.formats.missionfile import read_mission_file

    base = peak_rss_mb()
    start = time.perf_counter()
    try:
        read_mission_file(path)
        said = "read"
    except BridgeUsageError as err:
        said = str(err).split(": ", 1)[1][:60]
    print(json.dumps({"mb": peak_rss_mb() - base, "s": time.perf_counter() - start, "said": said}))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--items", type=int, default=1_000_000, help="items of the .waypoints case")
    parser.add_argument("--row", metavar="FILE", help=argparse.SUPPRESS)  # the child's mode
    args = parser.parse_args()
    if args.row:
        child(args.row)
        return 0
    from missionplan.bridge.formats.qgc_plan import MAX_JSON_BYTES

    with tempfile.TemporaryDirectory(prefix="limits-bench-") as folder:
        cases: list[tuple[str, Path]] = []
        path = Path(folder) / "many.waypoints"
        write_waypoints(path, args.items)
        cases.append((f".waypoints, {args.items:,} items", path))
        path = Path(folder) / "many.plan"
        write_plan(path, 70_000)
        cases.append((".plan, 70,000 items", path))
        path = Path(folder) / "huge.plan"
        with path.open("wb") as out:
            out.truncate(MAX_JSON_BYTES + 2**20)  # sparse: nothing written
        cases.append((f".plan of {(MAX_JSON_BYTES + 2**20) / 2**20:.0f} MiB (zeros)", path))
        path = Path(folder) / "compact.plan"
        per_item = len(json.dumps(ITEM, separators=(",", ":"))) + 1
        write_plan(path, (MAX_JSON_BYTES - 200) // per_item)
        cases.append((f".plan under the bound, {(MAX_JSON_BYTES - 200) // per_item:,} items", path))
        print(f"{'file':<40} {'size':>9} {'peak +MB':>9} {'s':>6}  answer")
        for name, path in cases:
            row = run_child_row([sys.executable, __file__, "--row", str(path)], timeout=600)
            size = f"{path.stat().st_size / 2**20:.1f} MiB"
            if isinstance(row, str):
                print(f"{name:<40} {size:>9} {row}")
            else:
                print(f"{name:<40} {size:>9} {row['mb']:>9.0f} {row['s']:>6.2f}  {row['said']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
