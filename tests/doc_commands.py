"""The shell commands of README.md and docs/*.md: find them, run them as written, compare their output.

Used by tests/test_docs_commands.py (which says what is checked); kept apart so that the parsing and
the comparison can be read, and tested, on their own.

Blocks. A fenced block is a *command block* when its language is a shell one (sh, bash, shell,
console), or it has no language and its first line that is not a `#` comment starts like a command
(`$ `, `missionplan`, `make`, `.venv/bin/`, `python`, `cd`, `pip`, `git`, `bash`, `./`), or any of its
lines starts with `$ `. In a block with `$ ` lines, those lines (and their `\\` continuations) are the
commands and the lines after each, up to the next `$ `, are what it printed. In a block without them,
every line that is not blank or a `#` comment is a command (with its continuations) and nothing is
shown as printed. A block with no command right after a command block (only blank lines between)
is what that block's last command printed.

A command block that cannot run here carries, on the last non-blank line before its fence,
`<!-- not run by the docs test: REASON -->`, REASON one of `REASONS`.

Output. A shown line must appear in the command's output (stdout and stderr, as a terminal shows
them), in the order shown; other lines may come between. Two lines are the same when their text
around the numbers is the same and each number is equal, except the numbers `MEASURED` names: those
measure this machine or this run, not the product (see there).
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import threading
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SHELL_LANGS = {"sh", "bash", "shell", "console", "shell-session"}
COMMAND_START = re.compile(r"^(\$ |(missionplan|make|python3?|cd|pip|git|bash)(\s|$)|\.venv/bin/|\./)")
FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})\s*([\w+-]*)\s*$")
NOT_RUN = re.compile(r"^\s*<!--\s*not run by the docs test:\s*(.*?)\s*-->\s*$")
# Why a block may stay unrun; the reason given must start with one of these.
REASONS = (
    "needs real hardware",          # a radio, a serial device, a vehicle
    "needs ArduCopter SITL",        # ../shared/sitl started by hand
    "needs PX4 SIH",                # ../shared/px4 started by hand
    "needs minutes of CPU",         # a benchmark run by hand: the reason names the time
    "is the CI command",            # make demo / make test: what CI runs (and the docs test is part of it)
)
# Numbers that measure this machine or this run. Each rule: a name, a pattern whose groups are the
# numbers it covers, and how far the run may be from the doc: None for any value (wall-clock
# seconds), or (relative, absolute) tolerances, either one enough (a mock flight paced by this
# machine's clock: at a speed-up its simulated flight advances by wall-clock steps and is sampled at
# the telemetry rate, so flown seconds and photo counts vary a little between runs). Every other
# number must be equal.
MEASURED: tuple[tuple[str, re.Pattern[str], tuple[float, float] | None], ...] = (
    ("wall seconds", re.compile(r"(\d+(?:\.\d+)?) s wall"), None),
    ("plan s", re.compile(r"^\s*plan s\s+(\d+\.\d+)"), None),
    ("transfer seconds", re.compile(r"; (\d+\.\d+) s$"), None),                  # upload / clear
    ("download seconds", re.compile(r" in (\d+\.\d+) s$"), None),               # download
    # the same mock flight has been seen to cover 99.80 % or 99.98 % instead of 100.00 % on a busy
    # machine (a few cells at the edge of a swath); fly passes from 99 %
    ("flown coverage", re.compile(r"^flown coverage (\d+\.\d+) % of"), (0.0, 0.5)),
    ("flown seconds", re.compile(r"(\d+\.\d+) s flown \(planned"), (0.03, 1.0)),
    ("flown photos", re.compile(r" s\), (\d+) photos, "), (0.03, 3.0)),
    ("flown closest approach", re.compile(r"^closest approach (\d+\.\d+) m horizontal / (\d+\.\d+) m 3-D;"), None),
    ("judge's tolerance", re.compile(r"\(tolerance (\d+\.\d+) m\)"), None),
    # a vehicle killed in a mock flight: when fly gave it up and at which item it was last heard
    ("lost vehicle", re.compile(r"link lost for (\d+) s since item (\d+) of"), None),
    # a survey's figures after a mock flight (status, replan, fly's survey line): the flown photos' spread
    ("survey photos", re.compile(r"flights? recorded, (\d+) photos$"), (0.03, 3.0)),
    ("survey cells", re.compile(r"^covered (\d+) of \d+ target cells: (\d+\.\d+) %, (\d+\.\d+) of"), (0.01, 0.5)),
    ("survey cells left", re.compile(r"recorded, (\d+) of \d+ target cells covered, (\d+) left$"), (0.03, 5.0)),
    ("survey coverage", re.compile(r"^survey \S+: (\d+\.\d+) % of \d+ target cells over"), (0.0, 0.5)),
    ("survey left", re.compile(r" flights, (\d+) left \("), (0.0, 10.0)),
    # geotag's cards are made from a mock flight's capture records: as many as the flown photos
    # (and the few records within microseconds of each other at a flight's start make its images ambiguous)
    ("geotag counts", re.compile(r"^card \S+: drone \d+, flights? [^:]+: (\d+) matched, \d+ unmatched images?, "
                                 r"(\d+) ambiguous, .*; (\d+) capture records? without an image$"), (0.15, 20.0)),
    ("geotag copies", re.compile(r"^wrote (\d+) geotagged cop"), (0.15, 40.0)),
)
NUMBER = re.compile(r"-?\d+(?:\.\d+)?")
IPV4 = re.compile(r"\b(\d{1,3}\.\d{1,3}\.\d{1,3}\.\d{1,3})\b")
LOOPBACK_PORT = re.compile(r"\b(127\.0\.0\.1|0\.0\.0\.0|localhost):(\d{2,5})\b")
FIRST_LINE_S = 30.0     # a background command must print its first line within this
COMMAND_S = 240.0       # a foreground command must end within this
STOP_S = 10.0           # a background command must stop within this after SIGINT


@dataclass
class Command:
    text: str                                   # as in the doc, continuations joined
    line: int                                   # 1-based line in the doc
    background: bool = False
    shown: list[str] = field(default_factory=list)   # what the doc shows it printed


@dataclass
class Block:
    doc: Path
    line: int                                   # 1-based line of the opening fence
    lang: str
    lines: list[str]
    marker: str | None = None                   # the not-run reason, if marked
    commands: list[Command] = field(default_factory=list)

    @property
    def where(self) -> str:
        return f"{self.doc.relative_to(ROOT)}:{self.line}"


def docs() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def fenced_blocks(doc: Path) -> list[tuple[Block, str]]:
    """Every fenced block of a doc, with the text between the previous block (or the start) and it."""
    text = doc.read_text().splitlines()
    blocks: list[tuple[Block, str]] = []
    i, since = 0, 0
    while i < len(text):
        m = FENCE.match(text[i])
        if not m:
            i += 1
            continue
        indent, fence, lang = m.group(1), m.group(2), m.group(3).lower()
        j = i + 1
        while j < len(text) and text[j].strip() != fence:
            j += 1
        body = [line[len(indent):] if line.startswith(indent) else line.lstrip() for line in text[i + 1:j]]
        before = [line for line in text[since:i] if line.strip()]
        marker = NOT_RUN.match(before[-1]) if before else None
        blocks.append((Block(doc, i + 1, lang, body, marker.group(1) if marker else None),
                       "\n".join(text[since:i])))
        i = since = j + 1
    return blocks


def is_command_block(block: Block) -> bool:
    if any(line.startswith("$ ") for line in block.lines):
        return True
    if block.lang in SHELL_LANGS:
        return True
    if block.lang:
        return False
    first = next((line for line in block.lines if line.strip() and not line.lstrip().startswith("#")), "")
    return bool(COMMAND_START.match(first))


def parse_commands(block: Block) -> list[Command]:
    """The block's commands, each with the lines shown as its output."""
    commands: list[Command] = []
    console = any(line.startswith("$ ") for line in block.lines)
    lines = block.lines
    i = 0
    while i < len(lines):
        line = lines[i]
        starts = line.startswith("$ ") if console else bool(line.strip()) and not line.lstrip().startswith("#")
        if not starts:
            if console and commands and line.strip():
                commands[-1].shown.append(line.rstrip())
            i += 1
            continue
        number = block.line + 1 + i
        parts = [line[2:] if console else line]
        while parts[-1].rstrip().endswith("\\") and i + 1 < len(lines):
            parts[-1] = parts[-1].rstrip()[:-1]
            i += 1
            parts.append(lines[i].strip())
        text = " ".join(p.strip() for p in parts)
        bare = strip_comment(text)
        background = bare.endswith("&") and not bare.endswith("&&")
        commands.append(Command(bare[:-1].rstrip() if background else bare, number, background))
        i += 1
    return commands


def strip_comment(text: str) -> str:
    """The command without a trailing `# comment` (a `#` outside quotes, after a space)."""
    quote: str | None = None
    for k, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (k == 0 or text[k - 1].isspace()):
            return text[:k].strip()
    return text.strip()


def command_blocks() -> list[Block]:
    """Every command block of the docs, with its commands and what each is shown printing."""
    out: list[Block] = []
    for doc in docs():
        previous: Block | None = None
        for block, between in fenced_blocks(doc):
            if is_command_block(block):
                block.commands = parse_commands(block)
                out.append(block)
                previous = block
                continue
            if previous is not None and previous.commands and not between.strip():
                previous.commands[-1].shown += [line.rstrip() for line in block.lines if line.strip()]
            previous = None
    return out


# ------------------------------------------------------------------------------------------ comparing
@dataclass(frozen=True)
class Line:
    template: str                               # the text with every number replaced by {}
    numbers: tuple[str, ...]
    rules: tuple[tuple[float, float] | None | str, ...]   # per number: "exact", None (any) or tolerances


def parse_line(text: str) -> Line:
    text = text.rstrip()
    measured: dict[int, tuple[float, float] | None] = {}
    for _name, pattern, tolerance in MEASURED:
        for m in pattern.finditer(text):
            for g in range(1, (pattern.groups or 0) + 1):
                measured[m.start(g)] = tolerance
    numbers, rules, template, last = [], [], [], 0
    for m in NUMBER.finditer(text):
        template.append(text[last:m.start()] + "{}")
        numbers.append(m.group())
        rules.append(measured.get(m.start(), "exact"))
        last = m.end()
    template.append(text[last:])
    return Line("".join(template), tuple(numbers), tuple(rules))


def same_line(shown: str, got: str) -> bool:
    a, b = parse_line(shown), parse_line(got)
    if a.template != b.template:
        return False
    for x, y, rule in zip(a.numbers, b.numbers, a.rules):
        if rule == "exact":
            if x != y:
                return False
        elif rule is not None:
            fx, fy = float(x), float(y)
            relative, absolute = rule  # type: ignore[misc]
            if abs(fx - fy) > max(relative * abs(fx), absolute):
                return False
    return True


def missing_lines(shown: list[str], got: list[str]) -> list[str]:
    """The shown lines that do not appear in `got` in order (empty when all do)."""
    k = 0
    for i, line in enumerate(shown):
        while k < len(got) and not same_line(line, got[k]):
            k += 1
        if k == len(got):
            return shown[i:]
        k += 1
    return []


def shows_an_error(shown: list[str]) -> bool:
    """A command whose shown output is an error may exit non-zero: a `missionplan...:` line or a problem."""
    return any(re.match(r"^(missionplan( \w+)?: (?!warning)|\s*problem: )", line) for line in shown)


FLYING_COMMANDS = ("demo", "fly", "verify")  # `missionplan demo` and `verify` fly mock fleets; `fly` the block's mock


def flies_mocks(block: Block) -> bool:
    """Whether a command of the block flies mock autopilots (`missionplan demo`, or `missionplan fly` against
    the mock the block starts): its test carries the `flight` marker."""
    for command in block.commands:
        words = command.text.split()
        if len(words) > 1 and words[0] == "missionplan" and words[1] in FLYING_COMMANDS and "--help" not in words:
            return True
    return False


# ------------------------------------------------------------------------------------------ running
def free_port() -> int:
    """A port free on 127.0.0.1 for both TCP and UDP a moment ago."""
    for _ in range(50):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as tcp:
            tcp.bind(("127.0.0.1", 0))
            port = tcp.getsockname()[1]
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
                try:
                    udp.bind(("127.0.0.1", port))
                except OSError:
                    continue
                return port
    raise RuntimeError("no free port on 127.0.0.1")


def loopback_only(block: Block) -> list[str]:
    """What in a runnable block would leave this machine (it must not)."""
    wrong = []
    for command in block.commands:
        for address in IPV4.findall(command.text):
            if address not in ("127.0.0.1", "0.0.0.0"):
                wrong.append(f"{command.text!r} names {address}")
        if re.search(r"/dev/tty|COM\d", command.text):
            wrong.append(f"{command.text!r} opens a serial device")
    return wrong


def port_map(block: Block) -> dict[int, int]:
    """Each fixed port of the block's commands -> a port free now."""
    ports = sorted({int(p) for c in block.commands for _h, p in LOOPBACK_PORT.findall(c.text)})
    return {port: free_port() for port in ports}


def substitute(text: str, ports: dict[int, int]) -> str:
    """The command with its fixed ports replaced and every listening address made 127.0.0.1."""
    return LOOPBACK_PORT.sub(lambda m: f"127.0.0.1:{ports[int(m.group(2))]}", text)


def unsubstitute(text: str, ports: dict[int, int]) -> str:
    """Output with the run's ports named as the doc names them."""
    for doc_port, run_port in ports.items():
        text = re.sub(rf"\b{run_port}\b", str(doc_port), text)
    return text


@dataclass
class Ran:
    command: Command
    code: int | None
    output: list[str]


class Background:
    """A command run with `&`: started in its own session, its output collected by a thread."""

    def __init__(self, command: Command, text: str, cwd: Path, env: dict[str, str]) -> None:
        self.command = command
        self.proc = subprocess.Popen(["bash", "-c", text], cwd=cwd, env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, start_new_session=True)
        self.lines: list[str] = []
        self.first = threading.Event()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))
            self.first.set()
        self.first.set()

    def wait_ready(self) -> bool:
        """Whether it printed its first line (a mock prints it once its port is bound) in time."""
        return self.first.wait(FIRST_LINE_S) and bool(self.lines) and self.proc.poll() is None

    def stop(self) -> int | None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)  # the mock's Ctrl-C
            try:
                self.proc.wait(STOP_S)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(STOP_S)
        self.reader.join(STOP_S)
        return self.proc.returncode


def run_foreground(text: str, cwd: Path, env: dict[str, str]) -> tuple[int | None, str]:
    proc = subprocess.Popen(["bash", "-c", text], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        out, _ = proc.communicate(timeout=COMMAND_S)
        return proc.returncode, out
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate(timeout=STOP_S)
        return None, out + f"\n[docs test: killed after {COMMAND_S:.0f} s]"


def workdir(tmp: Path, python_bin: Path) -> Path:
    """A folder laid out like the repository (its tracked top-level entries linked), with ../shared
    beside it when the repository has one and .venv pointing at the Python running the tests."""
    repo = tmp / "repo"
    repo.mkdir()
    try:
        tracked = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True,
                                 timeout=30).stdout.split()
        top = sorted({name.split("/")[0] for name in tracked})
    except (OSError, subprocess.SubprocessError):
        top = sorted(p.name for p in ROOT.iterdir() if not p.name.startswith("."))
    for name in top:
        if (ROOT / name).exists():
            (repo / name).symlink_to(ROOT / name)
    (repo / ".venv").symlink_to(python_bin.parent)
    shared = ROOT.parent / "shared"
    if shared.is_dir():
        (tmp / "shared").symlink_to(shared)
    return repo


def environment(python_bin: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = f"{python_bin}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONUNBUFFERED"] = "1"   # the background's first line as soon as it is printed
    env["MPLBACKEND"] = "Agg"
    env.pop("PYTHONPATH", None)
    return env


def run_block(block: Block, cwd: Path, env: dict[str, str]) -> list[Ran]:
    """Run the block's commands in order in cwd; background ones are stopped when the block ends."""
    ports = port_map(block)
    started: list[Background] = []
    done: list[Ran] = []
    try:
        for command in block.commands:
            text = substitute(command.text, ports)
            if command.background:
                bg = Background(command, text, cwd, env)
                started.append(bg)
                if not bg.wait_ready():
                    done.append(Ran(command, bg.proc.poll(), bg.lines + ["[docs test: no first line in time]"]))
                    return done
                continue
            code, out = run_foreground(text, cwd, env)
            done.append(Ran(command, code, unsubstitute(out, ports).splitlines()))
            if code != 0 and not shows_an_error(command.shown):
                return done
    finally:
        for bg in started:
            code = bg.stop()
            done.append(Ran(bg.command, 0 if code in (0, -signal.SIGINT, 130) else code,
                            unsubstitute("\n".join(bg.lines), ports).splitlines()))
    return done


# ------------------------------------------------------------------------------------------ measured tables
TABLE_BEGIN = re.compile(r"^<!-- table: (.+?) -->\s*$")
TABLE_END = re.compile(r"^<!-- end table -->\s*$")
DECIMAL = re.compile(r"(?<![\d.])\d+\.\d+(?![\d.])")  # 0.5, 12.34; not an address (127.0.0.1)


@dataclass
class Table:
    doc: Path
    line: int
    rows: list[str]
    command: str | None          # the `<!-- table: ... -->` around it, if any
    before: str                  # the prose between the previous table / block / marker and its marker

    @property
    def where(self) -> str:
        return f"{self.doc.relative_to(ROOT)}:{self.line}"


def looks_measured(rows: list[str], markdown: bool) -> bool:
    """A table of measured numbers: a markdown table whose data cells (first column aside) hold a
    decimal number in half of them or more (a table of settings or rules holds a few); a text block
    with three lines or more of two decimal numbers or more (bench output)."""
    if markdown:
        cells = [c for row in rows[2:] for c in row.strip().strip("|").split("|")[1:]]
        return len(rows) >= 4 and bool(cells) and sum(bool(DECIMAL.search(c)) for c in cells) * 2 >= len(cells)
    return sum(len(DECIMAL.findall(row)) >= 2 for row in rows) >= 3


def measured_tables(doc: Path) -> list[Table]:
    """The doc's measured tables: markdown tables, and fenced blocks that are neither commands nor
    what a shown command printed (those the command runs check)."""
    text = doc.read_text().splitlines()
    attached = {b.line for b in command_blocks() if b.doc == doc}
    output_of_command = _output_blocks(doc)
    found: list[Table] = []
    command: str | None = None
    since = 0
    i = 0
    while i < len(text):
        line = text[i]
        if m := TABLE_BEGIN.match(line):
            command, since_marker = m.group(1), "\n".join(text[since:i])
            i += 1
            continue
        if TABLE_END.match(line):
            command = None
            since = i + 1
            i += 1
            continue
        if fence := FENCE.match(line):
            j = i + 1
            while j < len(text) and text[j].strip() != fence.group(2):
                j += 1
            rows = text[i + 1:j]
            if (i + 1) not in attached and (i + 1) not in output_of_command and looks_measured(rows, False):
                found.append(Table(doc, i + 1, rows, command, since_marker if command else "\n".join(text[since:i])))
            if command is None:
                since = j + 1
            i = j + 1
            continue
        if line.lstrip().startswith("|"):
            j = i
            while j < len(text) and text[j].lstrip().startswith("|"):
                j += 1
            rows = text[i:j]
            if looks_measured(rows, True):
                found.append(Table(doc, i + 1, rows, command, since_marker if command else "\n".join(text[since:i])))
            if command is None:
                since = j
            i = j
            continue
        i += 1
    return found


def _output_blocks(doc: Path) -> set[int]:
    """Lines of the fenced blocks that show what the command block right before them printed."""
    out: set[int] = set()
    previous_was_command = False
    for block, between in fenced_blocks(doc):
        if is_command_block(block):
            previous_was_command = True
            continue
        if previous_was_command and not between.strip():
            out.add(block.line)
        previous_was_command = False
    return out


def bench_options(script: Path) -> set[str]:
    """The options a bench script's parser takes (its add_argument calls, and the doc-writing option)."""
    import ast

    options = {"--write-doc", "--help"}
    for node in ast.walk(ast.parse(script.read_text())):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument":
            options |= {a.value for a in node.args if isinstance(a, ast.Constant) and str(a.value).startswith("--")}
    return options


def table_command_problems(table: Table) -> list[str]:
    """Why a measured table's marker does not name a bench command that can write it (empty: fine)."""
    import shlex

    if table.command is None:
        return ["not between <!-- table: python bench/SCRIPT.py ... --> and <!-- end table -->"]
    try:
        tokens = shlex.split(table.command)
    except ValueError as err:
        return [f"marker command {table.command!r}: {err}"]
    if len(tokens) < 2 or tokens[0] not in ("python", "python3") or not re.fullmatch(r"bench/\w+\.py", tokens[1]):
        return [f"marker command {table.command!r} is not `python bench/SCRIPT.py ...`"]
    script = ROOT / tokens[1]
    if not script.is_file():
        return [f"marker command {table.command!r}: no {tokens[1]}"]
    problems = []
    known = bench_options(script)
    for token in tokens[2:]:
        if token.startswith("--") and token.split("=")[0] not in known:
            problems.append(f"marker command {table.command!r}: {tokens[1]} has no option {token.split('=')[0]}")
    if "--write-doc" not in script.read_text():
        problems.append(f"{tokens[1]} cannot write its table into a doc (no --write-doc)")
    named = " ".join(table.command.split()[1:])
    if named not in " ".join(table.before.split()):
        problems.append(f"the text before the table does not name its command `{named}`")
    return problems
