"""What installing missionplan costs: disk and start-up time of a fresh install from the built wheel.

For each install asked (`core`: the wheel alone; `train`: the wheel with the `train` extra, i.e. torch),
it builds the wheel of the working tree (or of a git revision, for a before / after comparison),
installs it with constraints.txt into a fresh venv in a temp folder, and measures:

- MB on disk of the whole venv (what `du -sm` says), and the seconds the install took;
- start-up: the median over several runs of `missionplan --help`,
  `python -c "import missionplan.planning.pipeline"`, loading the shipped network
  (`make_policy("nn")`), and a small plan with it (Leonardo, 3 drones, `--policy nn`),
  each from a temp folder, after one untimed warm-up run. Each as CPU seconds (user + system
  of the child: steady on a busy machine) / wall seconds.

Run by hand (it installs from the package registries and takes minutes; the timings move with
the machine's load):

    .venv/bin/python bench/install_bench.py                        # this tree: core and train
    .venv/bin/python bench/install_bench.py --rev 4ef6771 --installs core   # before: torch in core
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# The map by path, so the same command runs on a revision whose wheel did not carry the maps.
LEONARDO = ROOT / "maps" / "leonardo.map"


def run(command: list[str], cwd: Path | None = None) -> tuple[float, float]:
    """(CPU, wall) seconds of one run; raises with the command's output when it fails."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    began = time.perf_counter()
    done = subprocess.run(command, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - began
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} exited {done.returncode}:\n{done.stdout[-2000:]}{done.stderr[-2000:]}")
    return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, wall


def source_tree(rev: str | None, into: Path) -> Path:
    """The files to build: a git revision, or the working tree's files that git would commit."""
    into.mkdir()
    if rev is not None:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
        return into
    listed = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                            capture_output=True, check=True).stdout.split(b"\0")
    present = b"\0".join(name for name in listed if name and (ROOT / os.fsdecode(name)).exists())
    packed = subprocess.run(["tar", "-C", str(ROOT), "--null", "-T", "-", "-c"], input=present,
                            capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=packed, check=True)
    return into


def disk_mb(folder: Path) -> float:
    return int(subprocess.run(["du", "-sk", str(folder)], capture_output=True, text=True, check=True)
               .stdout.split()[0]) / 1024


def median_seconds(command: list[str], cwd: Path, runs: int) -> str:
    """'CPU / wall' medians."""
    run(command, cwd)  # warm-up: the first run also fills the file cache and writes .pyc files
    timed = [run(command, cwd) for _ in range(runs)]
    return f"{statistics.median(t[0] for t in timed):.2f} / {statistics.median(t[1] for t in timed):.2f}"


def measure(install: str, wheel: Path, constraints: Path | None, work: Path, runs: int) -> dict[str, object]:
    venv = work / f"venv-{install}"
    run([sys.executable, "-m", "venv", str(venv)])
    pin = ["-c", str(constraints)] if constraints is not None else []
    pip = [str(venv / "bin" / "pip"), "install", "--quiet", *pin]
    install_s = (run([*pip, "pip"] if pin else [*pip, "--upgrade", "pip"])[1]
                 + run([*pip, f"{wheel}[train]" if install == "train" else str(wheel)])[1])
    python, missionplan = str(venv / "bin" / "python"), str(venv / "bin" / "missionplan")
    has_torch = subprocess.run([python, "-c", "import importlib.util, sys; sys.exit(not importlib.util.find_spec('torch'))"]
                               ).returncode == 0
    cwd = work / f"cwd-{install}"
    cwd.mkdir()
    row = {
        "install": install, "torch": "yes" if has_torch else "no", "MB": disk_mb(venv), "install s": install_s,
        "--help": median_seconds([missionplan, "--help"], cwd, runs),
        "import pipeline": median_seconds([python, "-c", "import missionplan.planning.pipeline"], cwd, runs),
        "load nn": median_seconds([python, "-c", "from missionplan.planning.pipeline import make_policy; make_policy('nn')"],
                                    cwd, runs),
        "plan nn": median_seconds([missionplan, "plan", "--map", str(LEONARDO), "--uavs", "3", "--policy", "nn",
                                     "--out", str(cwd / "plan"), "--quiet"], cwd, max(3, runs // 2)),
    }
    subprocess.run(["rm", "-rf", str(venv)], check=True)  # about 1.4 GB with torch
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rev", help="build this git revision instead of the working tree (e.g. the commit before)")
    parser.add_argument("--installs", default="core,train", help="core, train or both (comma-separated)")
    parser.add_argument("--runs", type=int, default=7, help="timed runs per start-up measure (median)")
    args = parser.parse_args()
    installs = args.installs.split(",")
    if not set(installs) <= {"core", "train"}:
        parser.error("--installs: core, train")
    with tempfile.TemporaryDirectory(prefix="missionplan-install-bench.") as tmp:
        work = Path(tmp)
        source = source_tree(args.rev, work / "src")
        run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(work / "dist"), str(source)])
        wheel = next((work / "dist").glob("missionplan-*.whl"))
        constraints = source / "constraints.txt"
        rows = [measure(install, wheel, constraints if constraints.is_file() else None, work, args.runs)
                for install in installs]
    print(f"source: {args.rev or 'working tree'}; {os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f} "
          f"at the end; start-up: CPU s / wall s, medians of {args.runs} runs (plan: {max(3, args.runs // 2)})")
    columns = list(rows[0])
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))
    for row in rows:
        print("| " + " | ".join(f"{v:.0f}" if isinstance(v, float) else str(v) for v in row.values()) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
