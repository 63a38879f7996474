"""What `plan`, `replan` and `demo` print about a written plan folder: the metrics table, each drone's
mission, the separation and clearance kept, the warnings (stderr) and the files written.

Reads only the returned PlanFolder (missionplan/planning/plan_folder.py); plans and writes nothing. Text that came
from a file (the map's name, warnings naming buildings or files, the folder) is printed through printable():
a file's control characters never reach the terminal.
"""

from __future__ import annotations

import sys
from pathlib import Path

from missionplan.bridge.terminal_text import printable
from missionplan.geo.camera import CELLS_PER_FOOTPRINT

from ..mission.roof_targets import RoofTargets
from ..planning.plan_folder import PlanFolder

EXIT_FAILED = 1  # the exit status of a plan written whole that failed (targets left unreached)


def _fmt(value: float | int | None, digits: int = 1) -> str:
    if value is None:
        return "-"
    return f"{value:.{digits}f}" if isinstance(value, float) else str(value)


def _print_roofs(roofs: RoofTargets) -> None:
    """The target classes asked, the cell rule, the GSD at the ground and the highest roof, coverage per class."""
    asked = {"roofs": "the roofs low enough to overfly", "all": "the streets and the roofs low enough to overfly",
             "streets": "the streets"}[roofs.targets]
    print(f"  targets: {asked} (--targets {roofs.targets}); {roofs.rule}")
    if roofs.gsd_cm_at_ground is not None and roofs.gsd_cm_at_highest_roof is not None:
        print(f"  GSD {roofs.gsd_cm_at_ground:g} cm/px at the ground, {roofs.gsd_cm_at_highest_roof:g} cm/px at the "
              f"highest roof ({roofs.highest_roof_m:g} m)")
    for c in roofs.by_class:
        print(f"  coverage {c.name:<8} {c.pct:>5.1f} %  of the {c.targets} reachable {c.name[:-1]} cells")


def print_plan(folder: PlanFolder) -> None:
    """The plan's summary on stdout, its warnings and a failure on stderr."""
    record, written, options = folder.record, folder.written, folder.options
    ground, gmap = folder.ground, folder.ground.gmap
    m = record.metrics
    zones = options.zones + ("" if not options.balance_zones else ", balanced")
    print(f"map {printable(gmap.name)} ({gmap.shape[0]} x {gmap.shape[1]}), {ground.uavs} UAVs, policy {options.policy}, "
          f"zones {zones}, seed {options.seed}")
    coverage = record.coverage
    assert coverage is not None, "a written plan has its coverage"
    print(f"targets U = {record.targets} reachable, {record.unreachable} unreachable (set explored); "
          f"floor U/(9A) = {record.floor:.1f}")
    if record.lane_drones:
        spacing = options.lane_spacing_cells
        lanes = "footprint-wide lanes" if spacing == CELLS_PER_FOOTPRINT else f"lanes {spacing} cells apart"
        print(f"open ground: {record.lane_drones} of {ground.uavs} drones sweep their zone in {lanes} "
              "(--open-ground explore: cell by cell)")
    if record.tours is not None:
        print(f"  {record.tours.summary()}")
    rows = [("MMN", _fmt(m.mmn), "mean moves per drone"),
            ("TE %", _fmt(m.te), "trajectory efficiency"),
            ("MNT %", _fmt(m.mnt, 2), "weighted turns per move"),
            ("MUD*", _fmt(m.mud, 2), "mean drone spacing, steady state (cells)"),
            ("MDU*", _fmt(m.mdu, 2), "mean distance unexplored -> drone, steady state"),
            ("coverage %", _fmt(m.coverage), f"of the {record.targets} reachable targets"),
            ("coverage all", _fmt(coverage.all_pct),
             f"% of all {coverage.targets_all} targets ({record.unreachable} unreachable)"),
            ("makespan", _fmt(m.makespan), "moves of the busiest drone"),
            ("hover steps", _fmt(m.hover_steps), ""),
            ("MMN / floor", f"{m.mmn / record.floor:.2f}" if record.floor else "-", ""),
            ("plan s", f"{record.timing.plan_s:.2f}", "wall time, zones + planning")]
    for name, value, note in rows:
        print(f"  {name:<12} {value:>9}  {note}")
    if record.roofs is not None:
        _print_roofs(record.roofs)
    terrain = record.georeference.terrain if record.georeference is not None else None
    for drone in record.drones or ():
        before, after = drone.before, drone.after
        sorties = f" in {len(drone.sorties)} sorties" if len(drone.sorties) > 1 else ""
        above = ""
        if terrain is not None:
            flown = drone.above_ground_m
            above = " above the ground" + (f" ({flown[0]:g}-{flown[1]:g} m as flown)" if flown is not None else "")
        print(f"  uav{drone.id}: {drone.cells} cells -> {drone.waypoints} waypoints, "
              f"{drone.length_m:.0f} m, {drone.flight_s:.0f} s{sorties}, {drone.photos} photos "
              f"at {drone.altitude_m:g} m{above} (turning {before.turning_deg:.0f} -> {after.turning_deg:.0f} deg)")
    if folder.overlap is not None:  # measured from where the missions take their photos, not from the rule
        print(f"  overlaps as planned: {folder.overlap.summary()}")
    if record.overlap_fill is not None:
        print(f"  {record.overlap_fill.summary()}")
    if record.improve is not None:
        print(f"  {record.improve.summary()}")
    sep = record.separation
    if sep is not None and sep.d3 is not None:
        closest = sep.closest
        print(f"  closest approach if flown as planned: {closest.d3} m 3-D, {closest.horizontal} m horizontal "
              f"(uav{closest.pair_3d[0]} and uav{closest.pair_3d[1]} at {closest.at_s} s"
              f"{'' if len(sep.sorties) < 2 else ' of sortie ' + str(sep.sortie)}); "
              f"at least {sep.required_m:g} m guaranteed by {sep.method}")
    cl = record.clearance
    if cl is not None and cl.kept_m is not None:
        print(f"  clearance from obstacles: {cl.kept_m:g} m (asked {cl.required_m:g} m)")
        if cl.band is not None and cl.band.band_targets_missed and not coverage.unreachable_by_clearance:
            print(f"missionplan: warning: {cl.band.band_targets_missed} of the {cl.band.band_targets} target cells "
                  f"closer than --clearance {cl.required_m:g} m to an obstacle are out of every photo (narrow streets, "
                  f"courtyards); counted unreachable", file=sys.stderr)
    vertical = record.roofs.vertical if record.roofs is not None else None
    if vertical is not None:
        if vertical.kept_m is None:
            print("  clearance over roofs: no leg crosses a building")
        else:
            print(f"  clearance over roofs: {vertical.kept_m:g} m vertical at the least, over {vertical.roofs_crossed} "
                  f"buildings the legs cross (asked {vertical.required_m:g} m)")
        if not vertical.kept:
            print(f"missionplan: warning: a leg passes {vertical.kept_m:g} m over a roof, closer than the "
                  f"{vertical.required_m:g} m margin the roofs were overflown with", file=sys.stderr)
    if terrain is not None:
        sources = ", ".join(printable(Path(source).name) for source in terrain.sources)
        print(f"  ground: DEM {sources} ({', '.join(terrain.crs)}, {terrain.resolution_m:g} m pixels), "
              f"{terrain.lowest_m:g} to {terrain.highest_m:g} m above sea level under the area; every height is "
              f"above the ground under the drone (kept in {', '.join(terrain.files)})"
              + (f"; ArduPilot follows it on a {terrain.spacing_m} m terrain grid (TERRAIN_SPACING, set at upload)"
                 if terrain.spacing_m is not None else ""))
        off = [(d.id, d.altitude_m, d.above_ground_m) for d in record.drones or () if d.above_ground_m is not None
               and max(abs(d.above_ground_m[0] - d.altitude_m), abs(d.above_ground_m[1] - d.altitude_m)) > 2.0]
        for sysid, wanted, (low, high) in off:
            print(f"missionplan: warning: uav{sysid} would fly {low:g}-{high:g} m above the ground, not {wanted:g} m "
                  "within 2 m: the ground is steeper than its terrain grid follows (a finer DEM, or a higher "
                  "--altitude)", file=sys.stderr)
    elif record.georeference is not None:
        print("  ground: taken as flat (no --dem): heights are above the launch points")
    capture = record.georeference.capture if record.georeference is not None else None
    if capture is not None:
        print(f"  capture with {printable(capture.camera.label)}:")
        for line in capture.rule_lines():
            print(f"    {line}")
    for warning in coverage.warnings:
        print(f"missionplan: warning: {printable(warning)}", file=sys.stderr)
    for path in folder.kept:
        print(f"missionplan: warning: kept {printable(path)}: the earlier plan listed it, but it is not what that "
              f"plan wrote (changed since, or no checksum recorded); not removed", file=sys.stderr)
    missions = [p.name for p in written if p.suffix in (".plan", ".waypoints")]
    maps = [p.name for p in written if p.name not in missions]
    listed = ", ".join(["report.json", "plan.png", *maps])
    if missions:
        listed += f", {len(missions)} mission files ({missions[0]} ... {missions[-1]})"
    print(f"wrote {printable(folder.out)}: {printable(listed)}")
    if not record.success:
        print(f"missionplan: plan failed: {printable(record.failure)}", file=sys.stderr)
