"""What `verify` writes in its folder: verify.json (the settings, the engine, one row per run, the summary and the
verdict), rewritten whole and atomically after every run that finishes, so a stopped verify keeps every finished
run and `--resume` continues it; verify.png (the distributions, each promise marked) and verify.html (the
verdict, the summary, the picture and every row, one self-contained page).
"""

from __future__ import annotations

import base64
import hashlib
import html
import json
from pathlib import Path
from typing import Any

from missionplan.base.atomic import atomic_path, write_text_atomic
from missionplan.base.naming import Named
from missionplan.flight.flight_report import COVERAGE_OK

SCHEMA = 1
JSON_NAME, PNG_NAME, HTML_NAME = "verify.json", "verify.png", "verify.html"


class VerifyFolderError(ValueError):
    """verify.json that cannot be continued (another plan, other settings, damaged): one line."""


def plan_fingerprint(plan_dir: Path) -> str:
    """The plan's identity: one SHA-256 over its mission files (every uavK.plan, sorties included), what is flown."""
    digest = hashlib.sha256()
    for path in sorted(plan_dir.glob("uav*.plan")):
        digest.update(path.name.encode() + b"\0" + hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def write_json(out: Path, doc: dict[str, Any]) -> None:
    write_text_atomic(out / JSON_NAME, json.dumps(doc, indent=1) + "\n")


def read_for_resume(out: Path, plan: str, settings: dict[str, Any]) -> list[dict[str, Any]]:
    """The rows an earlier verify into `out` finished, when it verified the same plan with the same settings (its
    number of runs aside)."""
    path = out / JSON_NAME
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return []
    except (OSError, ValueError) as err:
        raise VerifyFolderError(f"{path}: cannot be read to resume ({err})") from None
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA or not isinstance(doc.get("rows"), list):
        raise VerifyFolderError(f"{path}: not a verify.json of schema {SCHEMA}")
    if doc.get("plan", {}).get("missions_sha256") != plan:
        raise VerifyFolderError(Named("{0}: verifies another plan (its mission files differ); choose another {out}",
                                      path))
    theirs = {k: v for k, v in doc.get("settings", {}).items() if k != "runs"}
    ours = {k: v for k, v in settings.items() if k != "runs"}
    if theirs != ours:
        differ = sorted(k for k in set(theirs) | set(ours) if theirs.get(k) != ours.get(k))
        fields = ", ".join(f"{{{key}}}" for key in differ)  # each setting, spelled by the front end
        raise VerifyFolderError(Named("{0}: was verified with another " + fields + "; give the same to resume, or "
                                      "choose another {out}", path))
    return [r for r in doc["rows"] if isinstance(r, dict) and isinstance(r.get("run"), int)]


def draw(out: Path, rows: list[dict[str, Any]], summary: dict[str, Any], title: str) -> Path:
    """verify.png: coverage, makespan, closest approach and the least battery left, each as the share of runs at or
    below a value (a CDF: robust for 5 runs or 5,000, and a promise reads off where it crosses the curve), with
    what was promised (or planned) marked."""
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .summary import battery_low

    flown = [r for r in rows if not r.get("error")]
    promised = summary.get("promised_m")
    panels = [
        ([r["coverage"] for r in flown if r.get("coverage") is not None], "coverage (%)",
         COVERAGE_OK, f"promised {COVERAGE_OK:g} %"),
        ([r["makespan_s"] for r in flown if r.get("makespan_s")], "makespan (s)",
         summary.get("planned_makespan_s"), "planned"),
        ([r["closest_m"] for r in flown if r.get("closest_m") is not None], "closest approach (m)",
         None if promised is None else promised - (summary.get("separation_tolerance_m") or 0.0),
         "promised less the judge's tolerance"),
        ([b * 100 for r in flown if (b := battery_low(r)) is not None], "least battery left of any drone (%)",
         None if summary.get("reserve") is None else summary["reserve"] * 100, "reserve"),
    ]
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5))
    for ax, (values, label, mark, mark_label) in zip(axes.flat, panels):
        if values:
            xs = sorted(values)
            shares = [(i + 1) / len(xs) for i in range(len(xs))]
            ax.step([xs[0], *xs], [0.0, *shares], where="post", color="tab:blue", marker="." if len(xs) <= 50 else None)
            ax.set_ylim(0.0, 1.05)
        else:
            ax.text(0.5, 0.5, "not measured", ha="center", va="center", transform=ax.transAxes)
        if mark is not None:
            ax.axvline(mark, color="tab:red", linestyle="--", label=f"{mark_label}: {mark:.1f}")
            ax.legend(loc="lower right", fontsize=8)
        ax.set_xlabel(label)
        ax.set_ylabel("share of runs at or below")
        ax.grid(alpha=0.3)
    fig.suptitle("\n".join(textwrap.wrap(title, 120)), fontsize=9)
    fig.tight_layout()
    path = out / PNG_NAME
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=90)
    plt.close(fig)
    return path


def write_html(out: Path, doc: dict[str, Any], png: Path | None) -> Path:
    """verify.html: one page, nothing fetched (the picture inlined)."""
    summary = doc["summary"]
    image = ("" if png is None or not png.is_file() else
             f'<img alt="distributions" src="data:image/png;base64,{base64.b64encode(png.read_bytes()).decode()}">')
    columns = ("run", "seed", "wind", "faults", "coverage", "makespan_s", "closest_m", "battery", "lost", "retask",
               "problems", "attempts", "error")

    def cells(row: dict[str, Any]) -> list[str]:
        c = row.get("conditions", {})
        faults = ", ".join(f"{f['kind']} uav{f['drone']}@{f['at_item']}" for f in c.get("faults", []))
        from .summary import battery_low

        low = battery_low(row)
        return [str(row.get("run")), str(row.get("seed")), f"{c.get('wind_mps', 0):.1f} m/s from "
                f"{c.get('wind_from_deg', 0):.0f}°", faults, _num(row.get("coverage")), _num(row.get("makespan_s")),
                _num(row.get("closest_m")), "" if low is None else f"{low * 100:.0f} %",
                " ".join(f"uav{k}" for k in row.get("drones_lost") or []), "; ".join(row.get("retask") or []),
                "; ".join(row.get("problems") or []), str(row.get("attempts", 1)), row.get("error") or ""]

    body = "".join("<tr>" + "".join(f"<td>{html.escape(v)}</td>" for v in cells(r)) + "</tr>" for r in doc["rows"])
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>verify: {html.escape(doc['plan']['dir'])}</title>
<style>body{{font-family:sans-serif;margin:1.5em}}td,th{{border:1px solid #ccc;padding:2px 6px;font-size:12px}}
table{{border-collapse:collapse}}pre{{background:#f4f4f4;padding:8px}}</style></head><body>
<h1>{html.escape(doc['plan']['dir'])}: {summary['runs']} simulated flights</h1>
<p><b>{html.escape(doc['verdict'])}</b></p>
<p>engine {html.escape(json.dumps(doc.get('engine', {})))}; settings {html.escape(json.dumps(doc['settings']))}</p>
{image}
<h2>Summary</h2><pre>{html.escape(json.dumps(summary, indent=1))}</pre>
<h2>Runs</h2><table><tr>{''.join(f'<th>{c}</th>' for c in columns)}</tr>{body}</table>
</body></html>
"""
    path = out / HTML_NAME
    write_text_atomic(path, page)
    return path


def _num(value: Any) -> str:
    return "" if value is None else f"{float(value):.1f}"
