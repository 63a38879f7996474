import json
import subprocess
import sys

import pytest

from missionplan.cli import main

CLI = [sys.executable, "-m", "missionplan"]


def run_cli(*args):
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=300)


def test_maps_lists_the_shipped_maps():
    out = run_cli("maps")
    assert out.returncode == 0
    for name in ("leonardo", "grid-city", "old-town", "river-city"):
        assert name in out.stdout


def test_plan_writes_report_and_picture(tmp_path):
    out = run_cli("plan", "--map", "leonardo", "--uavs", "3", "--out", str(tmp_path / "run"), "--seed", "2")
    assert out.returncode == 0, out.stderr
    assert "MMN" in out.stdout and "coverage %" in out.stdout
    report = json.loads((tmp_path / "run" / "report.json").read_text())
    for key in ("map", "uavs", "policy", "metrics", "targets", "unreachable", "timing", "paths", "grid"):
        assert key in report
    for key in ("MMN", "TE", "MNT", "MUD", "MDU", "coverage", "makespan", "hover_steps"):
        assert key in report["metrics"]
    assert report["map"] == "leonardo" and report["uavs"] == 3 and report["policy"] == "expert"
    assert report["seed"] == 2 and report["timing"]["plan_s"] > 0
    assert len(report["paths"]) == 3 and len(report["paths"][0]) == report["steps"] + 1
    assert len(report["grid"]) == 42 and len(report["grid"][0]) == 84
    png = (tmp_path / "run" / "plan.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    assert not [p for p in (tmp_path / "run").iterdir() if p.name.startswith(".")]  # no temp files left


def test_same_seed_same_plan(tmp_path):
    for name in ("a", "b"):
        assert main(["plan", "--map", "leonardo", "--uavs", "4", "--out", str(tmp_path / name), "--quiet"]) == 0
    a = json.loads((tmp_path / "a" / "report.json").read_text())
    b = json.loads((tmp_path / "b" / "report.json").read_text())
    assert a["paths"] == b["paths"] and a["metrics"] == b["metrics"]


def write_map(path, launch):
    path.write_text(f"name: box\nlaunch: {launch}\ngrid:\n#####\n#...#\n#.#.#\n#...#\n#####\n")


@pytest.mark.parametrize("args, message", [
    (["--map", "atlantis", "--uavs", "3"], "unknown map 'atlantis'"),
    (["--map", "leonardo", "--uavs", "0"], "--uavs 0: must be a number of drones, an integer from 1 to 254"),
    (["--map", "leonardo", "--uavs", "7"], "launch cells for 6 drones, 7 asked"),
    (["--map", "leonardo", "--uavs", "three"], "invalid int value: 'three'"),
    (["--map", "leonardo", "--uavs", "3", "--zones", "manhattan"], "invalid choice: 'manhattan'"),
])
def test_bad_arguments_one_line_exit_2(tmp_path, args, message):
    out = run_cli("plan", *args, "--out", str(tmp_path / "o"))
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], out.stderr
    assert not (tmp_path / "o" / "report.json").exists()


def test_launch_cell_in_an_obstacle(tmp_path):
    bad = tmp_path / "box.map"
    write_map(bad, "2,2")
    out = run_cli("plan", "--map", str(bad), "--uavs", "1", "--out", str(tmp_path / "o"))
    assert out.returncode == 2
    assert out.stderr.strip() == f"missionplan: {bad}: launch cell 1 (2, 2) is inside an obstacle"
    good = tmp_path / "good.map"
    write_map(good, "1,1")
    assert main(["plan", "--map", str(good), "--uavs", "1", "--out", str(tmp_path / "g"), "--quiet"]) == 0


def test_train_writes_weights_and_report_that_plan_can_use(tmp_path):
    pytest.importorskip("torch", reason="training needs the train extra (make test installs it)")
    weights = tmp_path / "small.npz"
    out = run_cli("train", "--out", str(weights), "--maps", "4", "--no-dagger", "--workers", "2", "--quiet")
    assert out.returncode == 0, out.stderr
    assert "106684 parameters" in out.stdout and "test confusion" in out.stdout
    assert "samples after augmentation and cleaning" in out.stdout
    report = json.loads(weights.with_suffix(".json").read_text())
    assert report["parameters"] == 106_684 and report["maps"] == 4
    assert report["samples"]["augmented"] == 8 * report["samples"]["raw"]
    assert 0 < report["final"]["test_accuracy"] <= 100
    assert len(report["final"]["test_confusion"]) == 4
    planned = run_cli("plan", "--map", "leonardo", "--uavs", "3", "--out", str(tmp_path / "run"),
                      "--policy", "nn", "--weights", str(weights), "--quiet")
    assert planned.returncode == 0, planned.stderr
    assert json.loads((tmp_path / "run" / "report.json").read_text())["policy"] == "nn"


def test_bad_weights_file_is_one_line_and_exit_2(tmp_path):
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"\x00" * 64)
    out = run_cli("plan", "--map", "leonardo", "--uavs", "3", "--out", str(tmp_path / "run"),
                  "--policy", "nn", "--weights", str(bad))
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "bad.pt" in out.stderr
    assert not (tmp_path / "run").exists()
