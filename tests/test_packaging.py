"""What a release installs: planning without torch, package data in the wheel, ranges and the exact lock.

The built wheel itself is installed and run by `make wheel-check` (.ci/wheel-check); these tests
guard, in seconds, what would break it or what it cannot see.
"""

import importlib.metadata
import os
import subprocess
import sys
import tomllib
from fnmatch import fnmatch
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
TRAIN_HINT = "pip install 'missionplan[train]'"

# Runs in a child process: torch made unimportable (as if not installed), then every import
# attempt of it fails, so a planning path that needed torch would fail here.
_WITHOUT_TORCH = """
import sys
sys.modules["torch"] = None
"""


def _python(code: str, cwd: Path, installed_only: bool = False) -> subprocess.CompletedProcess:
    """`code` in a child Python, in `cwd`, importing this tree's missionplan however it is installed (with
    installed_only, only as installed: the repository is not put on its path)."""
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    if not installed_only:
        env["PYTHONPATH"] = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=cwd, env=env)


def test_planning_help_and_every_module_but_training_run_without_torch(tmp_path):
    code = _WITHOUT_TORCH + f"""
import importlib, pkgutil
import missionplan, missionplan.bridge, missionplan.geo
from missionplan.cli import main
try:
    main(["--help"])
except SystemExit as done:
    assert done.code == 0, done.code
assert main(["plan", "--map", "leonardo", "--uavs", "3", "--policy", "nn", "--out", {str(tmp_path / "nn")!r},
             "--quiet"]) == 0
for package in (missionplan, missionplan.geo, missionplan.bridge):
    for module in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        if module.name != "missionplan.learn.training":
            importlib.import_module(module.name)
print("ok")
"""
    out = _python(code, tmp_path)
    assert out.returncode == 0 and out.stdout.endswith("ok\n"), out.stderr


def test_planning_with_the_network_never_imports_torch(tmp_path):
    """Even where torch is installed (make test installs it), planning does not load it."""
    code = f"""
import sys
from missionplan.cli import main
assert main(["plan", "--map", "leonardo", "--uavs", "3", "--policy", "nn", "--out", {str(tmp_path / "nn")!r},
             "--quiet"]) == 0
print(sorted(name for name in sys.modules if name.split(".")[0] == "torch"))
"""
    out = _python(code, tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1] == "[]"


def test_train_without_torch_says_how_to_get_it_in_one_line_exit_2(tmp_path):
    code = _WITHOUT_TORCH + f"""
from missionplan.cli import main
raise SystemExit(main(["train", "--out", {str(tmp_path / "w.npz")!r}, "--maps", "4", "--quiet"]))
"""
    out = _python(code, tmp_path)
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and TRAIN_HINT in out.stderr, out.stderr
    assert not (tmp_path / "w.npz").exists()


def _package_folder(package: str) -> Path:
    """The folder setuptools packs `package` from: under its longest package-dir prefix, else its dotted path."""
    mapped = PYPROJECT["tool"]["setuptools"].get("package-dir", {})
    parts = package.split(".")
    for cut in range(len(parts), 0, -1):
        prefix = ".".join(parts[:cut])
        if prefix in mapped:
            return ROOT.joinpath(mapped[prefix], *parts[cut:])
    return ROOT.joinpath(*parts)


def test_every_source_folder_and_data_file_goes_into_the_wheel():
    setuptools = PYPROJECT["tool"]["setuptools"]
    packages = set(setuptools["packages"])
    # Every folder of the three source folders that holds files is a listed package's folder
    # (an unlisted one is left out of the wheel, with a build warning at best).
    package_folders = {_package_folder(package) for package in packages}
    for top in ("missionplan", "geo", "bridge"):
        for folder in [ROOT / top, *(ROOT / top).rglob("*")]:
            if folder.is_dir() and folder.name != "__pycache__" and any(p.is_file() for p in folder.iterdir()):
                assert folder in package_folders, folder
    # Every listed package's data file matches a package-data pattern (a .py file is code, always in).
    for package in packages:
        patterns = setuptools["package-data"].get(package, [])
        for path in _package_folder(package).iterdir():
            if path.is_file() and path.suffix != ".py":
                assert any(fnmatch(path.name, pattern) for pattern in patterns), f"{path} would not ship"


def test_the_shipped_maps_and_weights_are_package_data():
    setuptools = PYPROJECT["tool"]["setuptools"]
    assert setuptools["package-dir"]["missionplan.maps.shipped"] == "maps"  # the maps stay in the top-level maps/
    from missionplan.maps.catalog import MAPS_DIR, shipped_map_names

    shipped = sorted(p.stem for p in (ROOT / "maps").glob("*.map"))
    assert {"leonardo", "grid-city", "old-town", "river-city"} <= set(shipped)
    assert shipped_map_names() == shipped and MAPS_DIR.is_dir()
    weights = sorted(p.name for p in (ROOT / "missionplan" / "learn" / "weights").iterdir() if p.is_file())
    assert weights == ["policy.json", "policy.npz"]  # one copy of the weights, the one numpy reads


def test_geo_and_bridge_install_inside_missionplan_only(tmp_path):
    """The folders geo/ and bridge/ import as missionplan.geo and missionplan.bridge, from the repository's files,
    and under no top-level name another distribution could also install (the wheel: .ci/wheel-check)."""
    assert PYPROJECT["tool"]["setuptools"]["package-dir"] == {
        "missionplan.maps.shipped": "maps", "missionplan.geo": "geo", "missionplan.bridge": "bridge"}
    code = """
import importlib.util
import missionplan.bridge.sim.mock, missionplan.geo.frame
print(importlib.util.find_spec("bridge"), importlib.util.find_spec("geo"))
print(missionplan.bridge.sim.mock.__file__)
print(missionplan.geo.frame.__file__)
"""
    out = _python(code, tmp_path, installed_only=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["None None", str(ROOT / "bridge" / "sim" / "mock.py"),
                                       str(ROOT / "geo" / "frame.py")]


def _lock() -> dict[str, str]:
    from packaging.utils import canonicalize_name

    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, sep, version = line.partition("==")
            assert sep and version and not any(c in version for c in "<>=!~,;"), f"not an exact pin: {line}"
            pins[canonicalize_name(name)] = version
    return pins


def test_dependencies_are_ranges_and_torch_an_exact_extra():
    for requirement in PYPROJECT["project"]["dependencies"]:
        assert "==" not in requirement and "<" in requirement and ">=" in requirement, requirement
        assert not requirement.startswith("torch"), "planning must not need torch"
    extras = PYPROJECT["project"]["optional-dependencies"]
    assert extras["train"] == ["torch==2.13.0"]  # the CPU build on these machines; any other pulls CUDA
    assert all("==" not in requirement for requirement in extras["test"])


def test_the_lock_pins_every_installed_dependency_at_its_installed_version():
    """Everything missionplan[train,terrain,geotag,cluster,test] needs, as installed here, is in constraints.txt at that
    version."""
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    lock = _lock()
    assert {"pip", "numpy", "torch", "pytest"} <= set(lock)
    todo, seen = [("missionplan", ("train", "terrain", "geotag", "cluster", "test")), ("pip", ())], set()
    while todo:
        name, extras = todo.pop()
        if canonicalize_name(name) in seen:
            continue
        seen.add(canonicalize_name(name))
        try:
            dist = importlib.metadata.distribution(name)
        except importlib.metadata.PackageNotFoundError:
            if name == "torch":
                continue  # the train extra is not installed here; the lock still has it (checked above)
            raise
        if name != "missionplan":
            assert lock.get(canonicalize_name(name)) == dist.version, f"{name} {dist.version} is not locked as installed"
        for text in dist.requires or []:
            requirement = Requirement(text)
            if requirement.marker is None or any(requirement.marker.evaluate({"extra": e}) for e in extras or ("",)):
                todo.append((requirement.name, tuple(requirement.extras)))
    assert len(seen) > 20
