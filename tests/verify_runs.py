"""What the verify tests share (tests/test_verify.py, tests/test_verify_engines.py): the plan they verify (Leonardo
for 3 drones, a run of it about 5 s at the default 20x), verify.json read back, and their bound on a few runs."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from missionplan.cli import main

FLY_S = 240.0  # wall seconds a verify of a few runs may take here, with room for a loaded machine


def leonardo_3(folder: Path) -> Path:
    root = folder / "leonardo-3"
    assert main(["plan", "--map", "leonardo", "--uavs", "3", "--out", str(root), "--quiet"]) == 0
    return root


def verify_doc(out: Path) -> dict[str, Any]:
    return json.loads((out / "verify.json").read_text())
