"""Every shell command shown in README.md and docs/*.md runs as written, and prints what the doc shows.

For each fenced command block of the docs (how blocks, commands and shown output are told apart:
tests/doc_commands.py), in order:

- a block marked `<!-- not run by the docs test: REASON -->` must give one of the allowed reasons
  (real hardware, ArduCopter SITL, PX4 SIH, minutes of CPU with the time named, the CI command);
  every other command block is run here, and passes only if every command in it ran;
- it runs in a fresh temporary folder laid out like the repository (its tracked top-level entries
  linked in, `../shared` beside it when the repository has one, `.venv` the Python running the
  tests), with that Python's bin folder first on PATH, so `missionplan`, `.venv/bin/python` and
  relative paths such as `examples/...` and `../shared/maps/...` work as written;
- on loopback only: a block naming any address but 127.0.0.1 or 0.0.0.0, or a serial device, fails
  (mark it as needing hardware); **every fixed port in a block (14550, 5760, 57600, ...) is replaced
  by a port picked free at run time, and 0.0.0.0 by 127.0.0.1**, and the output is compared with the
  doc's ports put back;
- a command ending in `&` runs in the background (the mock autopilot, `missionplan mock ...`); the
  next command starts once it has printed its first line (the mock prints it once its port is
  bound), within 30 s, and it is stopped (SIGINT, as Ctrl-C) when the block ends. Every foreground
  command must end within 240 s. Nothing sleeps;
- each command must exit 0, unless what the doc shows it printing is an error (a `missionplan: ...`
  line or a `problem:` line); each shown line must appear in its output, in order, numbers equal
  except those `doc_commands.MEASURED` names (wall-clock seconds, `plan s`, transfer seconds: any
  value; a mock flight's flown coverage: within 0.5 percentage point; its flown seconds and photo
  counts: within 3 % or 1 s / 3 photos; its flown closest approach and the judge's tolerance: any
  value, the verdict `kept` is compared).

And every table of measured numbers (a markdown table, or a text block of bench output) sits between
`<!-- table: python bench/SCRIPT.py ARGS -->` and `<!-- end table -->`, where SCRIPT exists, takes
every option named and can write the table (`--write-doc`), and the text right before names the
command.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

import doc_commands as dc

BLOCKS = dc.command_blocks()
RUNNABLE = [b for b in BLOCKS if b.marker is None]
MARKED = [b for b in BLOCKS if b.marker is not None]
SHARED = dc.ROOT.parent / "shared"
# Programs outside the repo a doc block may run, which .ci/run installs and a developer's machine may lack.
INDEPENDENT_READERS = ("ogr2ogr", "ogrinfo", "gdalinfo", "exiftool", "chromium", "sqlite3")


def test_the_docs_have_command_blocks_to_run() -> None:
    assert len(RUNNABLE) >= 5, [b.where for b in RUNNABLE]
    assert all(b.commands for b in BLOCKS), [b.where for b in BLOCKS if not b.commands]


@pytest.mark.parametrize("block", MARKED, ids=[b.where for b in MARKED])
def test_a_block_not_run_says_why_with_an_allowed_reason(block: dc.Block) -> None:
    reason = block.marker or ""
    assert reason.startswith(dc.REASONS), f"{block.where}: reason {reason!r} is not one of {dc.REASONS}"
    if reason.startswith("needs minutes of CPU"):
        assert any(ch.isdigit() for ch in reason), f"{block.where}: name the time it takes"


@pytest.mark.parametrize("block", [pytest.param(b, marks=pytest.mark.flight) if dc.flies_mocks(b) else b
                                   for b in RUNNABLE], ids=[b.where for b in RUNNABLE])
def test_a_command_block_runs_as_written_and_prints_what_the_doc_shows(block: dc.Block, tmp_path: Path) -> None:
    assert not (wrong := dc.loopback_only(block)), f"{block.where}: {wrong}; mark it as needing hardware"
    if any("../shared" in c.text for c in block.commands) and not SHARED.is_dir():
        pytest.skip(f"{block.where} reads ../shared, absent here")
    absent = sorted({tool for c in block.commands for tool in INDEPENDENT_READERS
                     if c.text.split()[:1] == [tool] and shutil.which(tool) is None})
    if absent:
        pytest.skip(f"{block.where} runs {', '.join(absent)}, not installed here (.ci/run installs it)")
    python_bin = Path(sys.executable).parent
    cwd = dc.workdir(tmp_path, python_bin)
    ran = dc.run_block(block, cwd, dc.environment(python_bin))
    by_command = {id(r.command): r for r in ran}
    for command in block.commands:
        r = by_command.get(id(command))
        assert r is not None, f"{block.where}: `{command.text}` (line {command.line}) did not run: " \
                              f"an earlier command failed:\n" + "\n".join(_report(x) for x in ran)
        if not dc.shows_an_error(command.shown):
            assert r.code == 0, f"{block.where}: `{command.text}` exited {r.code}:\n{_report(r)}"
        missing = dc.missing_lines(command.shown, r.output)
        assert not missing, (f"{block.where}: `{command.text}` (line {command.line}) did not print, in "
                             f"order:\n  " + "\n  ".join(missing) + f"\n{_report(r)}")


def _report(r: dc.Ran) -> str:
    tail = r.output[-40:]
    return f"--- `{r.command.text}` exit {r.code}, last {len(tail)} lines:\n" + "\n".join(tail)


TABLES = [t for doc in dc.docs() for t in dc.measured_tables(doc)]


def test_the_docs_have_measured_tables() -> None:
    assert len(TABLES) >= 5, [t.where for t in TABLES]


@pytest.mark.parametrize("table", TABLES, ids=[t.where for t in TABLES])
def test_a_measured_table_names_the_bench_command_that_writes_it(table: dc.Table) -> None:
    assert not (problems := dc.table_command_problems(table)), f"{table.where}: " + "; ".join(problems)


# ---------------------------------------------------------------------- the checker itself can fail
def test_shown_lines_must_appear_in_order_with_equal_numbers() -> None:
    got = ["map leonardo (42 x 84), 5 UAVs", "  coverage %       100.0  of the 1956 reachable targets",
           "  plan s            0.31  wall time, zones + planning"]
    assert dc.missing_lines(["  coverage %       100.0  of the 1956 reachable targets",
                             "  plan s            0.10  wall time, zones + planning"], got) == []
    assert dc.missing_lines(["  coverage %        99.9  of the 1956 reachable targets"], got) != []
    assert dc.missing_lines(["  plan s            0.10  wall time, zones + planning",
                             "map leonardo (42 x 84), 5 UAVs"], got) != []  # out of order
    assert dc.missing_lines(["map leonardo (42 x 84), 6 UAVs"], got) != []


def test_a_mock_flight_s_measurements_have_their_own_tolerance() -> None:
    shown = "  uav1: finished, 49.3 s flown (planned 49.2 s), 124 photos, holds the uploaded mission"
    assert dc.same_line(shown, "  uav1: finished, 49.6 s flown (planned 49.2 s), 126 photos, holds the uploaded mission")
    assert not dc.same_line(shown, "  uav1: finished, 55.0 s flown (planned 49.2 s), 124 photos, holds the uploaded mission")
    assert not dc.same_line(shown, "  uav1: finished, 49.3 s flown (planned 49.2 s), 140 photos, holds the uploaded mission")
    assert not dc.same_line(shown, "  uav1: finished, 49.3 s flown (planned 49.9 s), 124 photos, holds the uploaded mission")
    verdict = "closest approach 0.028 m horizontal / 2.0 m 3-D; the plan promised 2.0 m 3-D (tolerance 0.382 m): kept"
    assert dc.same_line(verdict, verdict.replace("0.028", "0.031").replace("0.382", "0.35"))
    assert not dc.same_line(verdict, verdict.replace(": kept", ": BROKEN"))
    assert not dc.same_line(verdict, verdict.replace("promised 2.0", "promised 1.9"))
    covered = "flown coverage 100.00 % of 1956 target cells (photos from camera); 5 drones, 30.7 s wall"
    assert dc.same_line(covered, covered.replace("100.00", "99.98").replace("30.7", "41.2"))
    assert not dc.same_line(covered, covered.replace("100.00", "99.40"))
    assert not dc.same_line(covered, covered.replace("1956", "1955"))


def test_a_block_that_flies_mock_autopilots_is_told_apart() -> None:
    flying = {b.where for b in RUNNABLE if dc.flies_mocks(b)}
    assert any(where.startswith("README.md") for where in flying) and len(flying) >= 5, flying
    assert not dc.flies_mocks(dc.Block(Path("x.md"), 1, "sh", [], commands=[
        dc.Command("missionplan fly --help", 2), dc.Command("missionplan plan --map leonardo --uavs 3 --out fly", 3)]))


def test_blocks_commands_and_markers_are_read_as_documented(tmp_path: Path) -> None:
    doc = dc.ROOT / "docs" / "x.md"
    text = ("Run it:\n\n<!-- not run by the docs test: needs ArduCopter SITL -->\n```sh\n"
            "missionplan mock --listen udpin:127.0.0.1:14550 &   # the mock\n"
            "missionplan fly survey \\\n    --connect udpout:127.0.0.1:14550\n```\n\n"
            "```\n$ missionplan maps\nleonardo  42 x 84\n$ missionplan plan --map x --uavs 1 --out o\n"
            "missionplan: unknown map x\n```\n\n```\n# a map\nname: tiny\n```\n")
    path = tmp_path / "x.md"
    path.write_text(text)
    blocks = [b for b, _ in dc.fenced_blocks(path)]
    assert [dc.is_command_block(b) for b in blocks] == [True, True, False]
    assert blocks[0].marker == "needs ArduCopter SITL"
    first = dc.parse_commands(blocks[0])
    assert [(c.text, c.background) for c in first] == [
        ("missionplan mock --listen udpin:127.0.0.1:14550", True),
        ("missionplan fly survey --connect udpout:127.0.0.1:14550", False)]
    second = dc.parse_commands(blocks[1])
    assert [c.shown for c in second] == [["leonardo  42 x 84"], ["missionplan: unknown map x"]]
    assert dc.shows_an_error(second[1].shown) and not dc.shows_an_error(second[0].shown)
    ports = {14550: 40001}
    assert dc.substitute("--connect udpin:0.0.0.0:14550", ports) == "--connect udpin:127.0.0.1:40001"
    assert dc.unsubstitute("on port 40001", ports) == "on port 14550"
    assert doc.parent.is_dir()


def test_measured_tables_are_told_from_other_tables() -> None:
    measured = ["| map | A | s |", "|---|---|---|", "| a | 3 | 1.25 |", "| b | 4 | 0.99 |"]
    words = ["| setting | default |", "|---|---|", "| ceiling | 120 m |", "| reserve | a fifth |"]
    assert dc.looks_measured(measured, True) and not dc.looks_measured(words, True)
    bench = ["leonardo  3  0.41  100.00", "leonardo  5  0.52  100.00", "grid-city 6  1.90   99.98"]
    addresses = ["--connect udpin:0.0.0.0:14550 or udpout:127.0.0.1:14550", "tcp:127.0.0.1:5760 tcp:10.0.0.2:5760",
                 "udpin:127.0.0.1:14550 serves udpout:127.0.0.1:14550"]
    assert dc.looks_measured(bench, False) and not dc.looks_measured(addresses, False)
