"""Fuzz the ``tipgeo`` command line with generated hostile and careless input.

Each input is a work folder holding generated files — a mutated tip spec, study
config, grinder / mill / laser machine file, sweep cache, G-code program,
scan, tissue test, 4×4 transform — and a command line that reads them (and
sometimes names one of them as its output, or passes a hostile option value).
The command runs as ``tipgeo.cli.main(argv)`` in a forked child of this
process (imports paid once; a fresh process state per input; a hang is ended
by ``--timeout``), and per input the harness records:

* ``rc`` — the exit code (a Python exception escaping ``main`` is ``99``:
  a traceback a user would see);
* ``traceback`` — whether stderr holds ``Traceback``;
* ``wall_s`` — wall time of the child;
* ``rss_mb`` — the child's peak resident set (``os.wait4`` rusage; includes
  the forked interpreter's baseline, reported as ``baseline_rss_mb``);
* ``left`` — files in the work folder that are neither inputs nor the
  command's named outputs after a refusal, and tipgeo temporaries or staging
  folders after any run;
* ``modified`` — inputs whose content hash (SHA-256) changed.

Run by hand, e.g. ``python benchmarks/fuzz_cli.py -n 10000 --seed 1 --jsonl
fuzz.jsonl``: prints a summary (counts by kind and exit code, tracebacks,
slowest and largest inputs, files left behind, inputs modified) and exits 1
when any traceback, leftover, modified input, over-time or over-memory input
(``--max-s``, ``--max-mb``) is found. ``tests/test_fuzz_cli.py`` runs it at a
small size. Lengths in mm, angles in degrees as in the files it mutates.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import os
import random
import resource
import shutil
import signal
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"

#: Values that broke parsers before, and plain hostile ones.
NASTY = ["1" + "0" * 400, "-1" + "0" * 400, "1e-300", "-1e308", "1e999", "0", "-0.0", "nan",
         "inf", "-inf", '"x"', "''", "[1, 2]", "{a = 1}", "true", "false", "[" * 600 + "]" * 600,
         "{b = " * 600 + "1" + "}" * 600, "1_000", "0x10", "9" * 30, "1e-12", "360", "-90",
         "89.999", "[]", "[[]]", '"../../escaped"', '"x\\n*INCLUDE, INPUT=evil.inp"', "-1",
         "1e9", "5000", '"' + "a" * 300 + '"', "[" + ", ".join(["1.0"] * 5000) + "]",
         '"/dev/zero"', '"/etc/passwd"', "2024-01-01", "0.0001", "1e6", "65", "4096"]
PROGRAM_VALUES = ["0", "-1", "1e300", "1" + "0" * 400, "$nope", "(1", "1/0", "1e-9", "99999999",
                  "$a+", "*", "F", "I0 J0", "CYCLES 0", "TIME 0,", "REPEAT 100000000", "G1",
                  "X1e308", "F0", "F-5", "G2 X1 Y1 I0 J0", "WAIT", "ENDREPEAT", "$x=1/0",
                  "G4 P1e9", "M30", "%", "N1", "X" + "9" * 40]
SCAN_VALUES = ["nan", "inf", "1e300", "-1e308", "x", "", "1 2", "1 2 3 4", "0 0 0", "1,2,3",
               "ply", "end_header", "\x00\x01"]


def _value(r: random.Random) -> str:
    k = r.random()
    if k < 0.5:
        return r.choice(NASTY)
    if k < 0.7:
        return repr(r.choice([r.uniform(-1e3, 1e3), r.uniform(-1, 1), 10 ** r.uniform(-30, 30),
                              -(10 ** r.uniform(-30, 30))]))
    if k < 0.85:
        return str(r.randint(-10 ** 6, 10 ** 6))
    alphabet = "abc_-./\\\n\"'=[]{}#*, 0123456789é\t"
    return json.dumps("".join(r.choice(alphabet) for _ in range(r.randint(0, 16))))


def mutate_lines(r: random.Random, text: str, value=_value, n_max: int = 3) -> str:
    """``text`` with 1 … ``n_max`` line-level mutations: a value replaced, a
    line deleted, duplicated or cut, a junk line, an unknown key."""
    lines = text.splitlines()
    for _ in range(r.randint(1, n_max)):
        if not lines:
            lines.append(f"x = {value(r)}")
            continue
        i = r.randrange(len(lines))
        kind = r.choice(["value"] * 8 + ["delete", "dup", "cut", "junk", "key"])
        if kind == "value":  # a line with a value, mostly
            with_value = [k for k, ln in enumerate(lines) if "=" in ln]
            i = r.choice(with_value) if with_value else i
        line = lines[i]
        if kind == "value" and "=" in line:
            lines[i] = line.split("=", 1)[0] + "= " + value(r)
        elif kind == "value":
            lines[i] = line + " " + value(r)
        elif kind == "delete":
            del lines[i]
        elif kind == "dup":
            lines.insert(i, line)
        elif kind == "cut":
            lines[i] = line[: r.randint(0, len(line))]
        elif kind == "junk":
            lines.insert(i, "".join(r.choice("[]={}\"'#.\\ abcx019\t") for _ in
                                    range(r.randint(0, 30))))
        else:
            lines.insert(i, f"{r.choice(['colour', 'feed', 'lo', 'name', 'x'])} = {value(r)}")
    return "\n".join(lines) + "\n"


def _strip_comments(text: str) -> str:
    return "\n".join(ln for ln in text.splitlines() if ln.strip() and not ln.lstrip()
                     .startswith("#")) + "\n"


@dataclass
class Case:
    """One generated input: the files to write (name → text or bytes), the
    command line (``{d}`` is the work folder), the inputs among the files and
    the outputs the command names."""

    kind: str
    files: dict
    argv: list
    inputs: list
    outputs: list = field(default_factory=list)


_SPECS = ["bevel-14G-xi15", "twoplane-14G-xi15", "threeplane-14G-xi15", "lancet-14G",
          "conical-14G-theta15", "helical-14G", "punch-C2", "punch-plain"]


def _sample(name: str) -> str:
    return _strip_comments((SAMPLES / name).read_text(encoding="utf-8"))


def gen_spec(r):
    text = mutate_lines(r, _sample(r.choice(_SPECS) + ".toml"))
    cmd = r.random()
    if cmd < 0.8:
        argv = ["angles", "{d}/spec.toml", "--step-deg", r.choice(["30", "45", "90"]), "--json"]
        return Case("spec", {"spec.toml": text}, argv, ["spec.toml"])
    argv = ["build", "{d}/spec.toml", "-o", "{d}/tip.stl", "--tolerance-um", "50", "--quiet"]
    return Case("spec-build", {"spec.toml": text}, argv, ["spec.toml"], ["tip.stl"])


def gen_option(r):
    """Cheap commands with hostile option values."""
    v = r.choice(["0", "-1", "1e-30", "1e30", "nan", "inf", "-inf", "1e-300", "4096", "65",
                  "0.0001", "1e9", "abc", "", "360", "1e-7"])
    spec = "{d}/spec.toml"
    files = {"spec.toml": _sample(r.choice(_SPECS[:4]) + ".toml")}
    argv = r.choice([
        ["angles", spec, "--step-deg", v, "--json"],
        ["angles", spec, "--step-deg", "45", "--harmonics", v, "--method", "fourier", "--json"],
        ["build", spec, "-o", "{d}/tip.stl", "--tolerance-um", v, "--quiet"],
        ["sweep", "{d}/study.toml", "--dry-run", "--workers", v, "--quiet"],
        ["forces", spec, "--speed-ratio", v, "--json"],
        ["forces", spec, "--speed-ratio", "1", "--theta-deg", v, "--json"],
        ["forces", spec, "--speed-ratio", "1", "--sweep", "0", "1", v, "--json"],
        ["laser", "punch-C2", "-o", "{d}/out.pgm", "--beam-diameter-um", v, "--quiet"],
        ["laser", "punch-C2", "-o", "{d}/out.pgm", "--feed-mm-min", v, "--quiet"],
        ["gcode", "check", "{d}/prog.pgm", "--max-moves", v, "--json"],
        ["gcode", "check", "{d}/prog.pgm", "--max-statements", v, "--json"],
        ["grind", "bevel-14G-xi15", "-o", "{d}/out.json", "--feed-mm-min", v, "--quiet"],
    ])
    if "{d}/study.toml" in argv:
        files["study.toml"] = _sample("bevel-study.toml")
    if "{d}/prog.pgm" in argv:
        files["prog.pgm"] = (SAMPLES / "punch-C2.pgm").read_text()
    outs = [Path(a).name for a in argv if a.startswith("{d}/") and
            Path(a).name not in files]
    return Case("option", files, argv, list(files), outs)


def gen_study(r):
    text = mutate_lines(r, _sample(r.choice(["bevel-study.toml", "helical-study.toml"])))
    return Case("study", {"study.toml": text}, ["sweep", "{d}/study.toml", "--dry-run",
                                                  "--quiet"], ["study.toml"])


def _machine_text(r, sample: str) -> str:
    base = _sample(sample)
    if r.random() < 0.3:  # a whole table of random keys and values
        keys = [ln.split("=", 1)[0].strip() for ln in base.splitlines() if "=" in ln]
        rows = [f"{r.choice(keys + ['colour', 'lo', 'hi'])} = {_value(r)}"
                for _ in range(r.randint(0, 6))]
        return "\n".join(rows) + "\n"
    return mutate_lines(r, base, n_max=4)


def gen_grinder(r):
    text = _machine_text(r, "machines/grinder.toml")
    spec = r.choice(["bevel-14G-xi15", "twoplane-14G-xi15", "conical-14G-theta15"])
    argv = ["grind", spec, "--machine", "{d}/m.toml", "-o", "{d}/out.json", "--quiet"]
    return Case("grinder", {"m.toml": text}, argv, ["m.toml"], ["out.json"])


def gen_mill(r):
    text = _machine_text(r, "machines/haas-vf2.toml")
    argv = ["mill", "bevel-14G-xi15", "--machine", "{d}/m.toml", "-o", "{d}/out.nc", "--quiet"]
    return Case("mill", {"m.toml": text}, argv, ["m.toml"], ["out.nc"])


def gen_laser(r):
    text = _machine_text(r, "machines/a3200-laser.toml")
    if r.random() < 0.5:
        argv = ["laser", "punch-C2", "--machine", "{d}/m.toml", "-o", "{d}/out.pgm", "--quiet"]
        return Case("laser", {"m.toml": text}, argv, ["m.toml"], ["out.pgm"])
    argv = ["gcode", "check", "{d}/prog.pgm", "--machine", "{d}/m.toml", "--json"]
    return Case("laser", {"m.toml": text, "prog.pgm": (SAMPLES / "punch-C2.pgm").read_text()},
                argv, ["m.toml", "prog.pgm"])


def gen_program(r):
    text = (SAMPLES / r.choice(["punch-C2.pgm", "appendix_c.pgm"])).read_text()
    lines = text.splitlines()
    for _ in range(r.randint(1, 4)):
        i = r.randrange(len(lines))
        kind = r.choice(["word", "word", "delete", "dup", "insert"])
        words = lines[i].split()
        if kind == "word" and words:
            j = r.randrange(len(words))
            head = words[j][:1] if words[j][:1].isalpha() and r.random() < 0.5 else ""
            words[j] = head + r.choice(PROGRAM_VALUES + [f"{r.uniform(-1e4, 1e4):.6g}"])
            lines[i] = " ".join(words)
        elif kind == "delete":
            del lines[i]
        elif kind == "dup":
            lines.insert(i, lines[i])
        else:
            lines.insert(i, r.choice(PROGRAM_VALUES))
    argv = ["gcode", "check", "{d}/prog.pgm", "--max-statements", "100000", "--max-moves",
            "20000", "--max-operations", "400000", "--json"]
    if r.random() < 0.3:
        argv.append("--lenient")
    return Case("program", {"prog.pgm": "\n".join(lines) + "\n"}, argv, ["prog.pgm"])


_STUDY = """name = "fuzz-study"
base = "bevel-14G-xi15"
[[variables]]
name = "xi_deg"
path = "cutters[0].xi_deg"
min = 15.0
max = 45.0
[design]
method = "grid"
levels = 2
[analysis]
method = "exact"
responses = ["theta_min_deg", "l_c_mm"]
[sweep]
workers = 1
cache = true
"""


def _forge_entry(r, entry: dict):
    e = json.loads(json.dumps(entry))
    how = r.choice(["result", "hash", "version", "key", "status", "response", "responses",
                    "extra", "format", "raw", "drop", "value"])
    res = e.get("result") if isinstance(e.get("result"), dict) else {}
    if how == "result":
        e["result"] = r.choice([None, [], "x", 1, {"status": "ok"}])
    elif how == "hash":
        e["content_hash"] = r.choice(["0" * 64, "", 1, None, "g" * 64])
    elif how == "version":
        e["tipgeo_version"] = r.choice(["0.0.0", 1, None, ""])
    elif how == "key":
        e["key"] = r.choice(["f" * 64, "../x", 1, None])
    elif how == "status":
        res["status"] = r.choice(["excellent", 3, None, "failed", "ok"])
    elif how == "response":
        rs = res.get("responses") or {}
        for k in list(rs)[:1]:
            rs[k] = r.choice(["15", True, None, [1], {"a": 1}, 1e308, -1e308, 1e9])
    elif how == "responses":
        res["responses"] = r.choice([[1.0], "x", None, {}, {"bogus": 1.0}])
    elif how == "extra":
        e[r.choice(["served", "x", ""])] = True
    elif how == "format":
        e["format"] = r.choice([1, 3, "2", None, 2.0])
    elif how == "drop":
        e.pop(r.choice(list(e) or ["x"]), None)
    elif how == "value":
        e[r.choice(list(e) or ["x"])] = _value(r)
    else:
        return r.choice(["{not json", "", "[1, 2]", "\xff\xfe", "[" * 5000 + "]" * 5000,
                         json.dumps(e).replace("1", "NaN", 1), "null", '"x"'])
    return json.dumps(e)


def gen_cache(r, template: Path | None):
    """A sweep over a two-point study whose cache (made once, genuine) has
    forged entries."""
    files = {"study.toml": _STUDY}
    cache_files = {}
    if template is not None:
        for p in sorted(template.rglob("*.json")):
            rel = str(p.relative_to(template.parent))
            cache_files[rel] = p.read_text()
        for rel in r.sample(sorted(cache_files), k=r.randint(1, len(cache_files))):
            try:
                cache_files[rel] = _forge_entry(r, json.loads(cache_files[rel]))
            except ValueError:
                pass
    files.update(cache_files)
    argv = ["sweep", "{d}/study.toml", "--cache-dir", "{d}/cache", "-o", "{d}/sweep.csv",
            "--workers", "1", "--quiet"]
    # the cache's entries are read and (when forged) rewritten: only the study is an input
    return Case("cache", files, argv, ["study.toml"], ["sweep.csv"])


def _scan_text(r, n: int) -> str:
    import math

    rows = []
    for _ in range(n):
        g = r.uniform(0, 2 * math.pi)
        rows.append(f"{1.054 * math.cos(g)!r} {1.054 * math.sin(g)!r} {r.uniform(-1, 0)!r}")
    for _ in range(r.randint(0, 3)):
        if rows and r.random() < 0.6:
            rows[r.randrange(len(rows))] = r.choice(SCAN_VALUES)
        else:
            rows.append(r.choice(SCAN_VALUES))
    return "\n".join(rows) + ("\n" if rows else "")


def gen_scan(r):
    """A small, broken scan (compare refuses most before registration)."""
    n = r.choice([0, 1, 2, 3, 20])
    ext = r.choice([".xyz", ".txt", ".ply", ".pts", ".csv"])
    text = _scan_text(r, n)
    if ext == ".ply" and r.random() < 0.7:
        text = (f"ply\nformat ascii 1.0\nelement vertex {r.choice([n, n + 5, 10 ** 12, -1])}\n"
                "property float x\nproperty float y\nproperty float z\nend_header\n" + text)
    argv = ["compare", "{d}/scan" + ext, "bevel-14G-xi15", "--quiet", "--no-pictures",
            "--out-dir", "{d}/report"]
    if r.random() < 0.5:
        argv.append("--no-register")
    return Case("scan", {"scan" + ext: text}, argv, ["scan" + ext], ["report"])


def gen_transform(r):
    rows = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    text = "\n".join(" ".join(str(x) for x in row) for row in rows) + "\n"
    text = mutate_lines(r, text, value=lambda r: r.choice(SCAN_VALUES + ["2", "1e300", "0"]))
    argv = ["compare", "{d}/scan.xyz", "bevel-14G-xi15", "--init-transform", "{d}/T.txt",
            "--no-register", "--quiet", "--no-pictures", "--out-dir", "{d}/report"]
    return Case("transform", {"T.txt": text, "scan.xyz": _scan_text(r, 3)}, argv,
                ["T.txt", "scan.xyz"], ["report"])


def gen_tissue(r):
    text = (SAMPLES / "tissue" / "pvc-sp0.25-synthetic.csv").read_text()
    text = mutate_lines(r, text, value=lambda r: r.choice(SCAN_VALUES + NASTY[:12]), n_max=5)
    argv = ["tissue", "fit", "{d}/t.csv", "--json", "--quiet"]
    return Case("tissue", {"t.csv": text}, argv, ["t.csv"])


def gen_collide(r):
    """An output that is one of the command's inputs, directly or through a
    file the input names (a mesh cutter, a study's base spec), or a report
    folder holding the scan: refused, nothing overwritten."""
    spec = _sample("bevel-14G-xi15.toml")
    k = r.randrange(6)
    if k == 0:
        return Case("collide", {"spec.stl": spec}, ["build", "{d}/spec.stl", "-o",
                                                    "{d}/spec.stl", "--quiet"], ["spec.stl"])
    if k == 1:
        base = r.choice(["base.toml", "base.csv"])
        study = _sample("bevel-study.toml").replace('base = "bevel-14G-xi15"',
                                                     f'base = "{base}"')
        return Case("collide", {"study.toml": study, base: spec},
                    ["sweep", "{d}/study.toml", "-o", "{d}/" + base, "--quiet"],
                    ["study.toml", base])
    if k == 2:
        import math

        rows = [f"{1.054 * math.cos(g)!r} {1.054 * math.sin(g)!r} {r.uniform(-1, 0)!r}"
                for g in (r.uniform(0, 2 * math.pi) for _ in range(200))]
        scan = (f"ply\nformat ascii 1.0\nelement vertex {len(rows)}\nproperty double x\n"
                "property double y\nproperty double z\nend_header\n" + "\n".join(rows) + "\n")
        return Case("collide", {"report/deviations.ply": scan},
                    ["compare", "{d}/report/deviations.ply", "bevel-14G-xi15", "--out-dir",
                     "{d}/report", "--quiet", "--no-pictures"], ["report/deviations.ply"])
    if k == 3:
        prog = (SAMPLES / "punch-C2.pgm").read_text()
        return Case("collide", {"prog.png": prog}, ["gcode", "check", "{d}/prog.png", "--png",
                                                    "{d}/prog.png"], ["prog.png"])
    if k == 4:
        m = _sample("machines/grinder.toml")
        return Case("collide", {"m.md": m}, ["grind", "bevel-14G-xi15", "--machine",
                                             "{d}/m.md", "--sheet", "{d}/m.md", "--quiet"],
                    ["m.md"])
    link = r.random() < 0.5
    prog = (SAMPLES / "punch-C2.pgm").read_text()
    return Case("collide", {"prog.pgm": prog, "link": ("hardlink" if link else "symlink",
                                                        "prog.pgm")},
                ["gcode", "check", "{d}/prog.pgm", "--mesh", "{d}/link.stl"], ["prog.pgm"])


#: Input kinds and their weights (cheap ones mostly; compare a little).
KINDS = {"spec": (gen_spec, 20), "option": (gen_option, 10), "study": (gen_study, 10),
         "grinder": (gen_grinder, 12), "mill": (gen_mill, 4), "laser": (gen_laser, 10),
         "program": (gen_program, 20), "cache": (None, 5), "scan": (gen_scan, 1.5),
         "transform": (gen_transform, 1), "tissue": (gen_tissue, 4), "collide": (gen_collide, 3)}


def _hash(p: Path) -> str | None:
    try:
        return hashlib.sha256(p.read_bytes()).hexdigest()
    except OSError:
        return None


def _write_case(case: Case, d: Path) -> None:
    for name, content in case.files.items():
        p = d / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, tuple):  # a link to another file of the case
            how, target = content
            if how == "hardlink":
                os.link(d / target, p.with_suffix(".stl"))
            else:
                os.symlink(d / target, p.with_suffix(".stl"))
            case.inputs.append(p.with_suffix(".stl").name)
        elif isinstance(content, bytes):
            p.write_bytes(content)
        else:
            p.write_text(content, encoding="utf-8", errors="surrogateescape")


def _child(argv: list[str], out_path: Path, max_mb: int) -> None:
    """Runs in the forked child: ``main(argv)`` with stdout/stderr to a file."""
    code = 98
    try:
        fd = os.open(out_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        sys.stdout = open(1, "w", closefd=False)  # noqa: SIM115
        sys.stderr = open(2, "w", closefd=False)  # noqa: SIM115
        if max_mb:
            lim = max_mb * (1 << 20)
            resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
        from tipgeo.cli import main

        try:
            code = main(argv)
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
        except BaseException:
            traceback.print_exc()
            code = 99
    finally:
        with contextlib.suppress(Exception):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(int(code) & 0xFF)


def _tree(d: Path) -> set[str]:
    return {str(p.relative_to(d)) for p in d.rglob("*")}


def run_case(case: Case, d: Path, *, timeout: float, as_mb: int) -> dict:
    """Write ``case`` into the empty folder ``d``, run it in a forked child
    and return its record."""
    _write_case(case, d)
    before = {n: _hash(d / n) for n in case.inputs}
    tree0 = _tree(d)
    argv = [a.replace("{d}", str(d)) for a in case.argv]
    log = d.parent / (d.name + ".log")
    t = time.perf_counter()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        signal.signal(signal.SIGALRM, signal.SIG_DFL)
        signal.alarm(int(timeout) + 1)
        _child(argv, log, as_mb)
    _, status, ru = os.wait4(pid, 0)
    wall = time.perf_counter() - t
    rc = os.waitstatus_to_exitcode(status)
    text = log.read_text(errors="replace") if log.exists() else ""
    log.unlink(missing_ok=True)
    after = {n: _hash(d / n) for n in case.inputs}
    modified = [n for n in case.inputs if before[n] != after[n]]
    extra = sorted(_tree(d) - tree0)
    temps = [n for n in extra if ".tipgeo" in n or n.endswith(".tmp")]
    if rc == 0:
        left = temps
    else:
        allowed = set(case.outputs) if rc == 1 else set()  # a verdict's outputs stay
        left = [n for n in extra if n not in allowed and n.split("/", 1)[0] not in allowed]
    last = [ln for ln in text.splitlines() if ln.startswith("tipgeo")] or \
        text.strip().splitlines()[-1:] or [""]
    return {"kind": case.kind, "argv": case.argv, "rc": rc,
            "traceback": "Traceback" in text or rc == 99, "wall_s": round(wall, 4),
            "rss_mb": round(ru.ru_maxrss / 1024, 1), "left": left, "modified": modified,
            "message": last[-1][:300],
            "files": {k: (v if isinstance(v, str) and len(v) < 4000 else f"<{len(v)} chars>")
                      for k, v in case.files.items() if not isinstance(v, tuple)}}


def _cache_template(work: Path) -> Path | None:
    """A genuine cache of the two-point study (made once by a forked run)."""
    d = work / "cache-template"
    d.mkdir()
    (d / "study.toml").write_text(_STUDY)
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        _child(["sweep", str(d / "study.toml"), "--cache-dir", str(d / "cache"), "-o",
                str(d / "sweep.csv"), "--workers", "1", "--quiet"], work / "template.log", 0)
    os.waitpid(pid, 0)
    cache = d / "cache"
    return cache if any(cache.rglob("*.json")) else None


_WARM = []


def _warm_up() -> None:
    """Import what the commands import, once, so each fork starts warm."""
    import io

    if _WARM:
        return
    _WARM.append(True)
    from tipgeo.cli import main

    with tempfile.TemporaryDirectory() as t, contextlib.redirect_stdout(io.StringIO()), \
            contextlib.redirect_stderr(io.StringIO()):
        for argv in (["angles", "bevel-14G-xi15", "--step-deg", "90", "--json"],
                     ["gcode", "check", str(SAMPLES / "punch-C2.pgm"), "--json"],
                     ["sweep", str(SAMPLES / "bevel-study.toml"), "--dry-run", "--quiet"],
                     ["laser", "punch-C2", "-o", f"{t}/l.pgm", "--quiet"],
                     ["grind", "bevel-14G-xi15", "-o", f"{t}/g.json", "--quiet"],
                     ["tissue", "list"]):
            with contextlib.suppress(BaseException):
                main(argv)
        with contextlib.suppress(BaseException):
            import tipgeo.inspect  # noqa: F401
            import tipgeo.inspect.scanio  # noqa: F401


def run_fuzz(n: int, seed: int = 0, *, kinds: list[str] | None = None, timeout: float = 60.0,
             as_mb: int = 2048, jsonl: Path | None = None, progress: bool = False,
             keep: bool = False) -> list[dict]:
    """Generate and run ``n`` inputs (seeded); their records, in order."""
    r = random.Random(seed)
    names = [k for k in KINDS if kinds is None or k in kinds]
    weights = [KINDS[k][1] for k in names]
    _warm_up()
    records = []
    work = Path(tempfile.mkdtemp(prefix="tipgeo-fuzz-"))
    out = open(jsonl, "w", encoding="utf-8") if jsonl else None  # noqa: SIM115
    try:
        template = _cache_template(work) if "cache" in names else None
        t0 = time.perf_counter()
        for i in range(n):
            kind = r.choices(names, weights)[0]
            case = gen_cache(r, template) if kind == "cache" else KINDS[kind][0](r)
            d = work / f"in{i}"
            d.mkdir()
            rec = run_case(case, d, timeout=timeout, as_mb=as_mb)
            rec["index"] = i
            records.append(rec)
            if out:
                out.write(json.dumps(rec) + "\n")
            if not keep:
                shutil.rmtree(d, ignore_errors=True)
            if progress and (i + 1) % 200 == 0:
                bad = sum(x["traceback"] for x in records)
                print(f"[fuzz] {i + 1}/{n} inputs, {time.perf_counter() - t0:.0f} s, "
                      f"{bad} tracebacks", file=sys.stderr, flush=True)
    finally:
        if out:
            out.close()
        if not keep:
            shutil.rmtree(work, ignore_errors=True)
    return records


def summary(records: list[dict], *, max_s: float = 5.0, max_mb: float = 300.0) -> tuple[str, bool]:
    """A plain-text summary of fuzz records and whether they are all clean."""
    from collections import Counter

    lines = [f"{len(records)} inputs"]
    by = Counter((x["kind"], x["rc"]) for x in records)
    for kind in sorted({k for k, _ in by}):
        lines.append(f"  {kind:<10} " + ", ".join(f"rc {rc}: {c}" for (k, rc), c in
                                                  sorted(by.items()) if k == kind))
    tb = [x for x in records if x["traceback"]]
    left = [x for x in records if x["left"]]
    mod = [x for x in records if x["modified"]]
    slow = sorted(records, key=lambda x: -x["wall_s"])
    big = sorted(records, key=lambda x: -x["rss_mb"])
    over = [x for x in records if x["wall_s"] > max_s or x["rss_mb"] > max_mb]
    lines.append(f"tracebacks: {len(tb)}")
    for x in tb[:20]:
        lines.append(f"  #{x['index']} {x['kind']}: {' '.join(x['argv'][:3])} … {x['message']}")
    lines.append(f"inputs with files left behind: {len(left)}")
    for x in left[:10]:
        lines.append(f"  #{x['index']} {x['kind']} rc {x['rc']}: {x['left'][:5]}")
    lines.append(f"inputs modified: {len(mod)}")
    for x in mod[:10]:
        lines.append(f"  #{x['index']} {x['kind']}: {x['modified']}")
    if records:
        walls = sorted(x["wall_s"] for x in records)
        lines.append(f"wall time per input: median {walls[len(walls) // 2]:.3f} s, "
                     f"max {walls[-1]:.3f} s; total {sum(walls):.0f} s")
        lines.append("slowest: " + "; ".join(f"#{x['index']} {x['kind']} {x['wall_s']:.2f} s "
                                             f"rc {x['rc']}" for x in slow[:5]))
        lines.append("largest peak RSS: " + "; ".join(f"#{x['index']} {x['kind']} "
                                                      f"{x['rss_mb']:.0f} MB rc {x['rc']}"
                                                      for x in big[:5]))
    lines.append(f"over {max_s:g} s or {max_mb:g} MB: {len(over)}")
    for x in over[:10]:
        lines.append(f"  #{x['index']} {x['kind']} {x['wall_s']:.2f} s {x['rss_mb']:.0f} MB "
                     f"rc {x['rc']}: {' '.join(x['argv'][:4])}")
    return "\n".join(lines), not (tb or left or mod or over)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-n", type=int, default=200, help="inputs to generate (default 200)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--kinds", nargs="*", choices=sorted(KINDS), default=None)
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per input (killed)")
    ap.add_argument("--address-space-mb", type=int, default=2048,
                    help="RLIMIT_AS of each child (0: none)")
    ap.add_argument("--max-s", type=float, default=5.0, help="target wall time per input")
    ap.add_argument("--max-mb", type=float, default=300.0, help="target peak RSS per input")
    ap.add_argument("--jsonl", type=Path, help="write one record per input here")
    ap.add_argument("--keep", action="store_true", help="keep the work folders")
    ap.add_argument("--summary-of", type=Path, nargs="+", metavar="JSONL",
                    help="summarise the records of earlier runs (e.g. parallel seeds); run "
                         "nothing")
    a = ap.parse_args(argv)
    if a.summary_of:
        recs = []
        for f in a.summary_of:
            with open(f, encoding="utf-8") as fh:
                recs += [json.loads(ln) | {"index": f"{f.stem}:{json.loads(ln)['index']}"}
                         for ln in fh if ln.strip()]
        text, clean = summary(recs, max_s=a.max_s, max_mb=a.max_mb)
        print(text)
        return 0 if clean else 1
    recs = run_fuzz(a.n, a.seed, kinds=a.kinds, timeout=a.timeout, as_mb=a.address_space_mb,
                    jsonl=a.jsonl, progress=True, keep=a.keep)
    text, clean = summary(recs, max_s=a.max_s, max_mb=a.max_mb)
    print(text)
    return 0 if clean else 1


if __name__ == "__main__":
    sys.exit(main())
