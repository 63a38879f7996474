"""Mission upload speed: items per second to the in-process mock autopilot on 127.0.0.1, and to real
ArduCopter SITL and PX4 SIH.

Run by hand: `.venv/bin/python bench/upload_bench.py [--sizes 100,1000] [--losses 0,0.2] [--backends pymavlink,mavsdk]
[--sitl-sizes 100,1000] [--px4-sizes 100,1000] [--px4-backends pymavlink,mavsdk] [--write-doc FILE]`.
For each backend, mission size and loss (the same in both directions, plus 5 % duplicates and 5 %
reordering when the loss is not 0) it uploads once and reads back once, and prints a table of
seconds and items per second. The mock re-requests a missing item after 10 ms and the ground
station's retry cap is 0.1 s (loopback settings: with the real-world 1.5 s a lossy transfer is
dominated by waiting). The ArduCopter rows upload with our pymavlink backend and its real-world
timing (1.5 s item time-out), next to the ArduPilot-flavoured mock with the same timing, to a fresh
SITL instance (../shared/sitl/arducopter, --speedup 10,
missionplan/testing/arducopter.py) over TCP, read back, verify by the ArduPilot rule, and count the
INVALID_SEQUENCE acks it sent (the upload must not race its re-requests: 0 expected). The PX4 SIH
rows (../shared/px4, missionplan/testing/px4_sih.py, a free instance, real time) use the same real-world
timing over PX4's offboard UDP link, and verify by PX4's rule (missionplan.bridge.formats.px4_rules.px4_stored).
No assertions: this is a measurement, not a test.
"""

from __future__ import annotations

import argparse
import contextlib
import time


from missionplan.bridge.formats.mission_items import (
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_MISSION,
    Flavour,
    Mission,
    MissionItem,
    to_wire,
)
from missionplan.bridge.formats.readback import compare_wire
from missionplan.bridge.sim.mock import LinkFaults, MockAutopilot
from missionplan.bridge.transfer.protocol import MissionTransferError, Timeouts
from missionplan.bridge.transfer.uploader import open_backend

import doctable  # bench/doctable.py: --write-doc


def survey(n: int) -> Mission:
    items = [MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=30.0)]
    items += [MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=1.0, x=45.07 + (i // 25) * 2e-4,
                          y=7.68 + (i % 25) * 1e-4, z=30.0)
              for i in range(n - 2)]
    return Mission(items + [MissionItem(CMD_NAV_RETURN_TO_LAUNCH, FRAME_MISSION)], home=(45.07, 7.68, 240.0))


def measure(backend: str, size: int, loss: float, seed: int) -> dict[str, object]:
    faults = LinkFaults.lossy(loss, duplicate=0.05 if loss else 0.0, reorder=0.05 if loss else 0.0, seed=seed)
    mission = survey(size)
    with MockAutopilot(flavour="px4", faults=faults, request_interval=0.01, upload_timeout=5.0) as mock:
        with open_backend(backend, mock.client_url, 1, timeouts=Timeouts(item_timeout=0.1, retries=30),
                          connect_timeout=5) as b:
            wire = to_wire(mission, b.vehicle.flavour)
            start = time.perf_counter()
            b.upload(0, wire)
            upload_s = time.perf_counter() - start
            start = time.perf_counter()
            got = b.download(0)
            read_s = time.perf_counter() - start
            reader = getattr(b, "read_back_by", backend)
        ok = not compare_wire(wire, got, skip_home=False) and not compare_wire(wire, mock.mission(1), skip_home=False)
    return {"upload_s": upload_s, "read_s": read_s, "reader": reader, "ok": ok}


def _timed_round_trip(b: object, wire: list, flavour: Flavour) -> dict[str, object]:
    """Upload `wire` and read it back on backend b: seconds for each and whether the vehicle holds it
    (by the flavour's stored-form rule; ArduPilot's home item is not ours to compare), or why refused."""
    start = time.perf_counter()
    try:
        b.upload(0, wire)  # type: ignore[attr-defined]
    except MissionTransferError as err:
        return {"refused": str(err)}
    upload_s = time.perf_counter() - start
    start = time.perf_counter()
    got = b.download(0)  # type: ignore[attr-defined]
    read_s = time.perf_counter() - start
    ok = not compare_wire(wire, got, skip_home=flavour is Flavour.ARDUPILOT, flavour=flavour)
    return {"upload_s": upload_s, "read_s": read_s, "ok": ok}


def measure_ardupilot(size: int, sitl: bool) -> dict[str, object]:
    """One upload and read-back with real-world timing, to ArduCopter SITL or the ArduPilot-flavoured
    mock (its 1 s re-requests, 650-item limit not imitated)."""
    from missionplan.testing.arducopter import ArduCopter  # free ports, own folder and session

    mission = survey(size)
    with contextlib.ExitStack() as stack:
        if sitl:
            url = stack.enter_context(ArduCopter(sysid=1)).url
        else:
            url = stack.enter_context(MockAutopilot(flavour="ardupilot")).client_url
        b = stack.enter_context(open_backend("pymavlink", url, 1, timeouts=Timeouts(), connect_timeout=20))
        wire = to_wire(mission, b.vehicle.flavour)
        # e.g. NO_SPACE refused: this SITL build holds 650 items, home included
        row = _timed_round_trip(b, wire, Flavour.ARDUPILOT)
        invalid = b.client.invalid_sequence_acks  # type: ignore[attr-defined]
    return {**row, "reader": f"pymavlink; {invalid} INVALID_SEQUENCE acks"} if "ok" in row else row


def measure_px4(size: int, backend: str) -> dict[str, object]:
    """One upload and read-back with real-world timing to a fresh PX4 SIH (../shared/px4, v1.15.4;
    missionplan/testing/px4_sih.py, a free instance, its offboard UDP link), verified by PX4's rule."""
    from missionplan.testing.px4_sih import PX4  # own temp folder and session, logging off, killed at exit

    home = (45.07, 7.68, 240.0)
    mission = survey(size)
    # PX4 refuses a take-off at 0, 0
    mission.items[0] = MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, x=home[0], y=home[1], z=30.0)
    with contextlib.ExitStack() as stack:
        vehicle = stack.enter_context(PX4(home=home))
        b = stack.enter_context(open_backend(backend, vehicle.offboard_url, vehicle.sysid, timeouts=Timeouts(),
                                             connect_timeout=20))
        wire = to_wire(mission, b.vehicle.flavour)
        row = _timed_round_trip(b, wire, Flavour.PX4)
    return {**row, "reader": getattr(b, "read_back_by", backend)} if "ok" in row else row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="100,1000")
    parser.add_argument("--losses", default="0,0.2")
    parser.add_argument("--backends", default="pymavlink,mavsdk")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--sitl-sizes", default="100,649,1000", help="ArduCopter SITL rows ('' for none)")
    parser.add_argument("--px4-sizes", default="100,1000", help="PX4 SIH rows ('' for none)")
    parser.add_argument("--px4-backends", default="pymavlink", help="backends for the PX4 SIH rows")
    doctable.add_option(parser)
    args = parser.parse_args()
    with doctable.Recorder(args.write_doc, __file__):
        return table(args)


def table(args: argparse.Namespace) -> int:
    sizes = [int(s) for s in args.sizes.split(",")]
    losses = [float(s) for s in args.losses.split(",")]
    backends = args.backends.split(",")
    print(f"{'vehicle':<16} {'backend':<10} {'items':>6} {'loss':>5} {'upload s':>9} {'items/s':>9} {'read s':>8} "
          f"{'items/s':>9}  {'verified':<8} read back by")
    for backend in backends:
        for size in sizes:
            for loss in losses:
                r = measure(backend, size, loss, args.seed)
                _row("mock (px4)", backend, size, loss, r)
    for size in [int(s) for s in args.sitl_sizes.split(",") if s.strip()]:
        _row("mock (ardupilot)", "pymavlink", size, 0.0, measure_ardupilot(size, sitl=False))
        _row("ArduCopter SITL", "pymavlink", size, 0.0, measure_ardupilot(size, sitl=True))
    for backend in args.px4_backends.split(","):
        for size in [int(s) for s in args.px4_sizes.split(",") if s.strip()]:
            _row("PX4 SIH", backend, size, 0.0, measure_px4(size, backend))
    return 0


def _row(vehicle: str, backend: str, size: int, loss: float, r: dict[str, object]) -> None:
    if "refused" in r:
        print(f"{vehicle:<16} {backend:<10} {size:>6} {loss:>5.0%}  {r['refused']}", flush=True)
        return
    up, read = float(r["upload_s"]), float(r["read_s"])  # type: ignore[arg-type]
    print(f"{vehicle:<16} {backend:<10} {size:>6} {loss:>5.0%} {up:>9.2f} {size / up:>9.0f} {read:>8.2f} "
          f"{size / read:>9.0f}  {'yes' if r['ok'] else 'NO':<8} {r['reader']}", flush=True)


if __name__ == "__main__":
    raise SystemExit(main())
