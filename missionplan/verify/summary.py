"""The runs' rows made into what a crew reads: percentiles of each measure, the share of runs that kept each
promise, and one verdict line.

The promises, each as `fly`'s judge holds a flight to it:
- coverage: at least COVERAGE_OK % of the target cells in confirmed photos;
- separation: the closest approach no less than the plan's promise less the judge's tolerance (the judge's `kept`);
- battery: every drone lands with at least the plan's reserve of its battery (the simulator's battery used,
  against the plan's endurance: flight_run.row_of);
- makespan has no promise: its percentiles are given against the plan's.
Runs that failed to fly at all (a row with `error`) are counted apart and kept out of the percentiles.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from missionplan.flight.flight_report import COVERAGE_OK

PERCENTILES = (5, 50, 95)


def _percentiles(values: list[float]) -> dict[str, float] | None:
    if not values:
        return None
    array = np.asarray(values, dtype=float)
    out = {f"p{p}": round(float(np.percentile(array, p)), 3) for p in PERCENTILES}
    return {**out, "min": round(float(array.min()), 3), "max": round(float(array.max()), 3)}


def battery_low(row: dict[str, Any]) -> float | None:
    """The least battery any drone of the run had left (share), None when not known."""
    left = row.get("battery_left") or {}
    return min(left.values()) if left else None


def reserve_broken(row: dict[str, Any]) -> bool:
    low, reserve = battery_low(row), row.get("reserve")
    return low is not None and reserve is not None and low < reserve


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """verify.json's `summary`: counts, percentiles and the share of runs that kept each promise."""
    flown = [r for r in rows if not r.get("error")]
    failed = [r for r in rows if r.get("error")]
    n = len(flown)
    coverage = [float(r["coverage"]) for r in flown if r.get("coverage") is not None]
    makespan = [float(r["makespan_s"]) for r in flown if r.get("makespan_s")]
    planned = next((float(r["planned_makespan_s"]) for r in flown if r.get("planned_makespan_s")), None)
    closest = [float(r["closest_m"]) for r in flown if r.get("closest_m") is not None]
    battery = [b for r in flown if (b := battery_low(r)) is not None]
    promised = next((r.get("promised_m") for r in flown if r.get("promised_m") is not None), None)
    tolerance = next((r.get("separation_tolerance_m") for r in flown if r.get("separation_tolerance_m")), 0.0)
    reserve = next((r.get("reserve") for r in flown if r.get("reserve") is not None), None)
    return {
        "runs": len(rows), "flown": n, "failed_to_fly": len(failed),
        "retried": sum(1 for r in rows if r.get("attempts", 1) > 1),
        "coverage_pct": _percentiles(coverage),
        "makespan_s": _percentiles(makespan), "planned_makespan_s": planned,
        "makespan_over_plan": (None if not makespan or not planned else
                               {k: round(v / planned - 1.0, 4) for k, v in (_percentiles(makespan) or {}).items()}),
        "closest_m": _percentiles(closest), "promised_m": promised, "separation_tolerance_m": tolerance,
        "battery_left": _percentiles(battery), "reserve": reserve,
        "kept": {
            "coverage": sum(1 for c in coverage if c >= COVERAGE_OK),
            "separation": sum(1 for r in flown if r.get("separation_kept") is not False),
            "battery_reserve": sum(1 for r in flown if not reserve_broken(r)) if battery else None,
        },
        "drones_lost": sum(len(r.get("drones_lost") or []) for r in flown),
        "retasks": _count([o for r in flown for o in r.get("retask") or []]),
        "problems": _count([p.split(":")[0] for r in flown for p in r.get("problems") or []]),
    }


def _count(values: list[str]) -> dict[str, int]:
    out: dict[str, int] = {}
    for v in values:
        out[v] = out.get(v, 0) + 1
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def _in(kept: int, n: int) -> str:
    return "in all" if kept == n else ("in none" if kept == 0 else f"in {kept} of {n} runs")


def verdict(summary: dict[str, Any]) -> str:
    """One line: "coverage >= 99 % in 97 of 100 runs; closest approach >= 12.1 m in all; makespan p95 +18 % over
    the plan; battery reserve broken in 2 runs"."""
    n, kept = summary["flown"], summary["kept"]
    if n == 0:
        return f"no run flew ({summary['failed_to_fly']} failed to fly)"
    parts = [f"coverage >= {COVERAGE_OK:g} % {_in(kept['coverage'], n)}"]
    closest, promised = summary["closest_m"], summary["promised_m"]
    if promised is not None and closest is not None:
        floor = max(promised - (summary["separation_tolerance_m"] or 0.0), 0.0)
        parts.append(f"closest approach >= {floor:.1f} m {_in(kept['separation'], n)} (least {closest['min']:.1f} m)")
    over = summary["makespan_over_plan"]
    if over is not None:
        pct = over["p95"] * 100
        parts.append(f"makespan p95 {pct:+.0f} % over the plan" if abs(pct) >= 1 else
                     f"makespan p95 {pct:+.1f} % over the plan")
    if kept["battery_reserve"] is not None:
        broken = n - kept["battery_reserve"]
        parts.append(f"battery reserve broken in {broken} run{'s' if broken != 1 else ''}" if broken
                     else f"battery reserve ({summary['reserve'] * 100:.0f} %) kept in all")
    if summary["failed_to_fly"] or summary["retried"]:
        parts.append(f"{summary['failed_to_fly']} failed to fly, {summary['retried']} retried after a worker died")
    return "; ".join(parts)
