"""`missionplan train` with the shipped seed reproduces the shipped weights' training run (what the training report
beside the shipped weights, missionplan/learn/weights/policy.json, recorded).

The whole run (seven DAgger rounds) takes about 45 minutes, so the suite repeats its first stage, the imitation of
the expert's demonstrations before any DAgger round (`--no-dagger`, about a minute): the same 100 training maps,
the expert's 46,136 recorded pairs and the cleaned dataset to the sample, the same epochs and a test accuracy
within ACCURACY_TOLERANCE points of the shipped run's. On this machine type with torch 2.13.0 (CPU) the run gives
the shipped run's figures exactly, its confusion matrix included; the tolerance allows another CPU or torch build,
which adds the floats in another order. The DAgger rounds that follow are seeded the same way (tests/test_network.py
checks a round's bookkeeping on a small run).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from missionplan.cli.app import main
from missionplan.learn.network import SHIPPED_WEIGHTS

pytest.importorskip("torch", reason="PyTorch is not installed (pip install 'missionplan[train]'; make test installs it)")

ACCURACY_TOLERANCE = 0.3  # percentage points of test accuracy against the shipped run's first stage


def test_the_shipped_seed_reproduces_the_first_stage_of_the_shipped_training(tmp_path: Path) -> None:
    out = tmp_path / "policy.npz"
    # One worker: the suite's simulated flights run beside it on two cores.
    assert main(["train", "--out", str(out), "--no-dagger", "--quiet", "--workers", "1"]) == 0
    ours = json.loads(out.with_suffix(".json").read_text())
    shipped = json.loads(Path(SHIPPED_WEIGHTS).with_suffix(".json").read_text())
    assert (ours["seed"], ours["maps"], ours["parameters"]) == (shipped["seed"], shipped["maps"], shipped["parameters"])
    assert ours["samples"] == shipped["samples"]  # the expert's demonstrations and their cleaning, to the sample
    assert (ours["epochs"], ours["best_epoch"]) == (shipped["epochs"], shipped["best_epoch"])
    for split in ("train_accuracy", "validation_accuracy", "test_accuracy"):
        assert abs(ours[split] - shipped[split]) <= ACCURACY_TOLERANCE, (split, ours[split], shipped[split])
