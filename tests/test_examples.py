"""Every ``tipgeo …`` command shown in README.md and docs/**/*.md runs (issue 24).

How examples are written in the Markdown (docs/reference/examples.md says the
same for authors):

- a ``console`` block: ``$ tipgeo …`` lines are commands, the lines after one
  (up to the next ``$``) are output it must print — each quoted line matches
  one line of the command's stdout, in order (lines may be left out between
  them); a quoted line starting with ``tipgeo:`` (a warning or error) matches
  stderr instead;
- a ``sh`` block: lines starting with ``tipgeo `` are commands, no output
  quoted (``\\`` continues a line);
- a block with a ``title="NAME"`` (a TOML study, a spec) is written to NAME
  before the file's next command runs, so commands can use it;
- a trailing ``# exit N`` states the exit code (default 0); ``# not run:
  REASON`` keeps a command that cannot run here (a Dask cluster's address) out,
  and :data:`NOT_RUN` lists each such command, so none slips in unnoticed;
  any other ``# comment`` is dropped.

A command that exits 3 (an external tool such as CalculiX is missing) skips
its file's test with the tool's install line instead of failing it; CI
installs every tool, so there they all run.

The commands of one Markdown file run in order in one temporary folder (later
commands read earlier outputs) holding the repository's ``samples/`` at
``samples/``, with ``TIPGEO_PROGRESS=off`` and a cache of their own.

A quoted line matches an output line when their words are equal and every
number is equal within one unit of its last printed digit (2.523 matches 2.5234
and 2.5226; a number printed without decimals compares as an integer ± 1);
``…`` in a quoted line stands for anything (timings, paths).
"""

from __future__ import annotations

import math
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]

#: Commands shown but not run, (file, command): each needs what CI has not.
NOT_RUN = {
    ("docs/tutorials/optimise.md",
     "tipgeo sweep bevel-study.toml --scheduler tcp://host:8786"),
}

#: The exit code of a command whose external tool (ccx, OCP, Dask, pyarrow)
#: is missing: its example is skipped, with the tool's install line, not failed.
MISSING_TOOL = 3

#: Seconds one command may take before the example counts as failed.
COMMAND_TIMEOUT_S = 300

# --------------------------------------------------------------------------
# The matcher: a quoted line against an output line
# --------------------------------------------------------------------------

WILDCARD = "…"

_TOKEN = re.compile(r"""
    (?P<wild>…)
  | (?P<word>[^\W\d](?:[\w.\-]*\w)?)                       # names: tip.stl, bevel-14G-xi15, λ
  | (?P<num>[-+−]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)
  | (?P<punct>\S)
""", re.VERBOSE)


@dataclass(frozen=True)
class Number:
    """A number as printed: its value and the unit of its last digit."""

    text: str
    value: float
    unit: float

    @classmethod
    def parse(cls, text: str) -> Number:
        t = text.replace("−", "-")
        mantissa, _, exponent = t.lower().partition("e")
        decimals = len(mantissa.partition(".")[2])
        unit = 10.0 ** ((int(exponent) if exponent else 0) - decimals)
        return cls(text, float(t), unit)

    def matches(self, value: float) -> bool:
        """Within one unit of the last printed digit (with float slack)."""
        return abs(value - self.value) <= self.unit * (1 + 1e-9) + 1e-12 * abs(self.value)


def tokens(line: str) -> list:
    """Words (str), numbers (:class:`Number`) and the wildcard (``…``) of a
    line; whitespace only separates."""
    out = []
    for m in _TOKEN.finditer(line):
        kind = m.lastgroup
        if kind == "num":
            out.append(Number.parse(m.group()))
        else:
            out.append(m.group())
    return out


def _same(expected, actual) -> bool:
    if isinstance(expected, Number):
        return isinstance(actual, Number) and expected.matches(actual.value)
    return not isinstance(actual, Number) and expected == actual


def line_matches(expected: str, actual: str) -> bool:
    """Does the quoted line ``expected`` match the output line ``actual``?

    Words equal, numbers within one unit of the quoted number's last digit,
    ``…`` any run of tokens (none included); whitespace is not compared."""
    exp, act = tokens(expected), tokens(actual)
    # glob matching over tokens, WILDCARD as '*'
    reach = [True] + [False] * len(act)  # reach[j]: exp[:i] matches act[:j]
    for e in exp:
        if e == WILDCARD:
            for j in range(1, len(act) + 1):
                reach[j] = reach[j] or reach[j - 1]
            continue
        new = [False] * (len(act) + 1)
        for j in range(1, len(act) + 1):
            new[j] = reach[j - 1] and _same(e, act[j - 1])
        reach = new
    return reach[len(act)]


def unmatched(expected: list[str], stdout: str, stderr: str) -> tuple[str, list[str]] | None:
    """The first quoted line with no match in order, and the lines it was
    looked for in; None when every quoted line matches."""
    streams = {"stdout": stdout.splitlines(), "stderr": stderr.splitlines()}
    at = {"stdout": 0, "stderr": 0}
    for line in expected:
        if not line.strip():
            continue
        name = "stderr" if line.lstrip().startswith("tipgeo:") else "stdout"
        lines = streams[name]
        for k in range(at[name], len(lines)):
            if line_matches(line, lines[k]):
                at[name] = k + 1
                break
        else:
            return line, lines[at[name]:]
    return None


# --------------------------------------------------------------------------
# Reading the examples out of the Markdown
# --------------------------------------------------------------------------

@dataclass
class Command:
    """One ``tipgeo …`` command of a Markdown file."""

    text: str
    line: int
    expected: list[str] = field(default_factory=list)
    exit_code: int = 0
    not_run: str | None = None


@dataclass
class WriteFile:
    """A titled block whose text is written to ``name`` before the next command."""

    name: str
    text: str
    line: int


_FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>`{3,}|~{3,})\s*(?P<info>.*)$")
_TITLE = re.compile(r"""title\s*=\s*(["'])(?P<title>[^"']+)\1""")
_ANNOTATION = re.compile(r"\s+#\s*(?P<comment>.*)$")


def _command(text: str, line: int) -> Command:
    """A command with its trailing ``# …`` annotation read and removed."""
    cmd = Command(text.strip(), line)
    m = _ANNOTATION.search(cmd.text)
    if m:
        comment = m.group("comment").strip()
        cmd.text = cmd.text[:m.start()].rstrip()
        if (e := re.fullmatch(r"exit\s+(\d+)", comment)):
            cmd.exit_code = int(e.group(1))
        elif comment.startswith("not run:"):
            cmd.not_run = comment[len("not run:"):].strip() or "no reason given"
    return cmd


def examples(markdown: str) -> list:
    """The commands and files of a Markdown text, in order."""
    out: list = []
    lines = markdown.splitlines()
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, info = len(m.group("indent")), m.group("fence"), m.group("info")
        start = i + 1
        body = []
        i += 1
        while i < len(lines) and not (lines[i].strip().startswith(fence)
                                      and lines[i].strip().strip(fence[0]) == ""):
            body.append(lines[i][indent:] if lines[i][:indent].strip() == "" else lines[i])
            i += 1
        i += 1
        lang = info.split()[0].lower() if info.split() else ""
        lang = lang.lstrip("{.").rstrip("}")
        title = _TITLE.search(info)
        if lang == "console":
            current = None
            for k, text in enumerate(body):
                if text.startswith("$ "):
                    current = _command(text[2:], start + k + 1)
                    if current.text.startswith("tipgeo "):
                        out.append(current)
                    else:
                        current = None  # not ours: neither run nor its output read
                elif current is not None:
                    current.expected.append(text)
        elif lang in ("sh", "bash", "shell"):
            k = 0
            while k < len(body):
                text, first = body[k], k
                while text.rstrip().endswith("\\") and k + 1 < len(body):
                    k += 1
                    text = text.rstrip()[:-1].rstrip() + " " + body[k].strip()
                if text.strip().startswith("tipgeo "):
                    out.append(_command(text, start + first + 1))
                k += 1
        elif title:
            out.append(WriteFile(title.group("title"), "\n".join(body) + "\n", start))
    return out


def markdown_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def _with_commands() -> list[Path]:
    return [p for p in markdown_files()
            if any(isinstance(x, Command) for x in examples(p.read_text(encoding="utf-8")))]


# --------------------------------------------------------------------------
# Running them
# --------------------------------------------------------------------------

def _environment(tmp: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env.update(TIPGEO_PROGRESS="off", MPLBACKEND="Agg", XDG_CACHE_HOME=str(tmp / ".cache"),
               TIPGEO_PYTHON=sys.executable, COLUMNS="100", PYTHONHASHSEED="0")
    return env


def run_command(cmd: Command, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    """``cmd`` in bash (redirections work), ``tipgeo`` being this Python's
    ``python -m tipgeo`` so the code under test runs."""
    script = 'tipgeo() { "$TIPGEO_PYTHON" -m tipgeo "$@"; }\n' + cmd.text
    return subprocess.run(["bash", "-c", script], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=COMMAND_TIMEOUT_S)


def _report(path: str, cmd: Command, result, why: str) -> str:
    def tail(text, n=25):
        lines = text.splitlines()
        return "\n".join(("    " + x) for x in lines[-n:]) or "    (nothing)"

    return (f"{path}:{cmd.line}: $ {cmd.text}\n  {why}\n  exit code {result.returncode}"
            f"\n  stdout (last lines):\n{tail(result.stdout)}\n  stderr (last lines):\n"
            f"{tail(result.stderr)}")


@pytest.mark.examples
@pytest.mark.parametrize("path", _with_commands(), ids=_rel)
def test_examples_run(path: Path, tmp_path: Path):
    """Each command of the file runs, exits as stated and prints what is quoted."""
    rel = _rel(path)
    (tmp_path / "samples").symlink_to(ROOT / "samples", target_is_directory=True)
    env = _environment(tmp_path)
    failures, missing_tool = [], []
    for item in examples(path.read_text(encoding="utf-8")):
        if isinstance(item, WriteFile):
            target = tmp_path / item.name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(item.text, encoding="utf-8")
            continue
        if item.not_run:
            assert (rel, item.text) in NOT_RUN, (
                f"{rel}:{item.line}: `{item.text}` is marked not run ({item.not_run}) but is "
                "not in tests/test_examples.py NOT_RUN")
            continue
        result = run_command(item, tmp_path, env)
        if result.returncode == MISSING_TOOL != item.exit_code:
            # an external tool this machine lacks (ccx, OCP, …): not a failure here
            missing_tool.append(f"{rel}:{item.line}: {result.stderr.strip()[-300:]}")
            continue
        if result.returncode != item.exit_code:
            failures.append(_report(rel, item, result, f"expected exit code {item.exit_code}"))
            continue
        miss = unmatched(item.expected, result.stdout, result.stderr)
        if miss is not None:
            failures.append(_report(rel, item, result,
                                    f"no output line matches the quoted line {miss[0]!r}"))
    assert not failures, "\n\n".join(failures)
    if missing_tool:
        pytest.skip("an external tool is missing (exit 3): " + "; ".join(missing_tool))


def test_not_run_is_the_list():
    """The commands marked ``# not run`` are exactly :data:`NOT_RUN`."""
    marked = {(_rel(p), x.text) for p in markdown_files()
              for x in examples(p.read_text(encoding="utf-8"))
              if isinstance(x, Command) and x.not_run}
    assert marked == NOT_RUN


def test_every_command_is_parsed():
    """Every command line is seen by the runner (a ``$ tipgeo`` line of a
    console block, a ``tipgeo`` line of a sh block), no other fenced block
    shows a ``tipgeo`` command (they would not run), and shlex splits each."""
    total = 0
    for p in markdown_files():
        text = p.read_text(encoding="utf-8")
        found = [x for x in examples(text) if isinstance(x, Command)]
        for cmd in found:
            shlex.split(cmd.text)
        total += len(found)
        in_fences = 0
        fenced = False
        lang = ""
        for line in text.splitlines():
            m = _FENCE.match(line)
            if m:
                fenced = not fenced
                lang = (m.group("info").split() or [""])[0] if fenced else ""
                continue
            s = line.strip()
            if fenced and ((lang == "console" and s.startswith("$ tipgeo "))
                           or (lang in ("sh", "bash", "shell") and s.startswith("tipgeo "))):
                in_fences += 1
            elif fenced and lang not in ("console", "sh", "bash", "shell"):
                assert not re.match(r"(\$ )?tipgeo [a-z]", s), (
                    f"{_rel(p)}: `{s}` in a {lang or 'plain'} block would not run; show it "
                    "in a console or sh block, or as prose")
        assert len(found) == in_fences, _rel(p)
    assert total > 0


# --------------------------------------------------------------------------
# The matcher's own tests
# --------------------------------------------------------------------------

def test_matcher_examples():
    assert line_matches("scallop 2.523 µm", "scallop 2.5234 µm")
    assert line_matches("scallop 2.523 µm", "scallop 2.5226 µm")
    assert line_matches("scallop 2.523 µm", "scallop   2.522 µm")
    assert not line_matches("scallop 2.523 µm", "scallop 2.521 µm")
    assert line_matches("9616 moves", "9617 moves")
    assert not line_matches("9616 moves", "9618 moves")
    assert line_matches("built in … s", "built in 0.016 s")
    assert line_matches("λ 0.12… 78.74°", "λ   0.12… 78.74°")
    assert line_matches("…", "anything at all 1 2 3")
    assert line_matches("wrote tip.stl", "wrote tip.stl")
    assert not line_matches("wrote tip.stl", "wrote tip.ply")
    assert not line_matches("wrote tip.stl", "wrote tip.stl and more")
    assert line_matches("wrote tip.stl …", "wrote tip.stl and more")
    assert not line_matches("outer 1.5 mm", "inner 1.5 mm")
    assert line_matches("mean −0.00 µm", "mean +0.00 µm")
    assert line_matches("error 1.1e-13°", "error 1.1368683772161603e-13°")
    assert not line_matches("bevel-14G-xi15", "bevel-14G-xi14.5")
    assert line_matches('"l_c_mm": 17.534,', '"l_c_mm": 17.533964530810717,')


_precision = st.integers(min_value=0, max_value=6)
_values = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(_values, _precision)
def test_rounded_number_matches(x, p):
    """A number printed at any precision matches the full number."""
    assert line_matches(f"F {x:.{p}f} N", f"F {x!r} N")
    assert line_matches(f"F {x:.{p}f} N", f"F {x:.{p + 3}f} N")


@settings(max_examples=300, deadline=None)
@given(_values, _precision, st.sampled_from([-1, 1]))
def test_two_units_off_does_not_match(x, p, sign):
    """Two units of the last printed digit away is not a match."""
    unit = 10.0 ** -p
    off = round(x, p) + sign * 2 * unit
    if not math.isfinite(off) or abs(off) * 1e-12 > unit / 4:  # beyond float precision
        return
    assert not line_matches(f"F {off:.{p}f} N", f"F {x!r} N")


@settings(max_examples=200, deadline=None)
@given(st.text(alphabet="abcdefxyzλθµ_", min_size=1, max_size=8),
       st.text(alphabet="abcdefxyzλθµ_", min_size=1, max_size=8), _values)
def test_different_words_do_not_match(a, b, x):
    """Lines differing in a word never match, whatever the numbers."""
    if a == b:
        return
    assert not line_matches(f"{a} {x:.3f}", f"{b} {x:.3f}")
    assert line_matches(f"{a} {x:.3f}", f"{a} {x:.3f}")


def test_reading_blocks():
    md = "\n".join([
        "text",
        "```console",
        "$ tipgeo gauges",
        "gauge  d_e_mm",
        "  14G  2.1080",
        "$ tipgeo build bevel-14G-xi15 -o t.stl  # exit 1",
        "$ ls",
        "t.stl",
        "```",
        "```sh",
        "tipgeo samples helical-14G > my.toml   # a spec to start from",
        "tipgeo sweep study.toml \\",
        "    --workers 2",
        "tipgeo sweep study.toml --scheduler tcp://h:1  # not run: a cluster",
        "python -m pytest",
        "```",
        '```toml title="study.toml"',
        'base = "bevel-14G-xi15"',
        "```",
        "  ```sh",
        "  tipgeo gauges",
        "  ```",
    ])
    got = examples(md)
    cmds = [x for x in got if isinstance(x, Command)]
    assert [c.text for c in cmds] == [
        "tipgeo gauges", "tipgeo build bevel-14G-xi15 -o t.stl",
        "tipgeo samples helical-14G > my.toml", "tipgeo sweep study.toml --workers 2",
        "tipgeo sweep study.toml --scheduler tcp://h:1", "tipgeo gauges"]
    assert cmds[0].expected == ["gauge  d_e_mm", "  14G  2.1080"]
    assert cmds[1].exit_code == 1 and cmds[1].expected == []
    assert cmds[4].not_run == "a cluster"
    files = [x for x in got if isinstance(x, WriteFile)]
    assert files[0].name == "study.toml" and files[0].text == 'base = "bevel-14G-xi15"\n'


def test_quoted_lines_in_order_and_streams():
    out = "a 1\nb 2\nc 3\n"
    err = "tipgeo: warning: --plot is deprecated; use --png\n"
    assert unmatched(["a 1", "c 3"], out, err) is None
    assert unmatched(["c 3", "a 1"], out, err)[0] == "a 1"
    assert unmatched(["tipgeo: warning: --plot is deprecated; use --png", "b 2"], out, err) is None
    assert unmatched(["d 4"], out, err)[0] == "d 4"
