"""The one table of A3200 AeroBasic commands tipgeo reads.

Every statement keyword the parser accepts is a row of :data:`COMMANDS` and
every row is accepted: the parser dispatches on the row's ``parser`` (which
statement parser reads it) and the interpreter on the syntax-tree node that
parser makes. Each row says what the command's arguments are, what it does,
and how the simulator treats it:

``modelled``  changes the simulated toolpath, its time, the beam or the state
              that later moves use;
``recorded``  moves nothing the simulation follows: parsed, then listed by
              ``tipgeo gcode check`` as "no motion" with its effect and count;
``ignored``   parsed and checked, no effect on the simulated path and no
              record (``ENABLE``, ``PSOOUTPUT``, ``G17`` …);
``refused``   a move tipgeo cannot simulate: an error in every mode.

G codes are rows of :data:`G_CODES` (a block's ``G`` words), word letters rows
of :data:`WORD_LETTERS`. Adding a command is one row here plus, when it moves
something, one handler in :mod:`gcode.motion` (G codes and words) or
:mod:`gcode.interpreter` (statements).

Units: lengths mm (inches after ``ENGLISH``/``G70``), angles degrees, times s
(feeds per second or per minute after ``MINUTES``/``G75``).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Command", "GCode", "COMMANDS", "G_CODES", "WORD_LETTERS", "MODELLED", "RECORDED",
           "IGNORED", "REFUSED", "commands_by_parser", "table_markdown"]

MODELLED, RECORDED, IGNORED, REFUSED = "modelled", "recorded", "ignored", "refused"


@dataclass(frozen=True)
class Command:
    """One statement keyword.

    Attributes
    ----------
    keyword : str — upper-case first word of the statement
    syntax : str — its arguments, as written after it
    effect : str — what it does (the "no motion" record's text when recorded)
    simulated : str — :data:`MODELLED`, :data:`RECORDED` or :data:`REFUSED`
    parser : str — the statement parser that reads it (the method
        ``st_<parser>`` of :class:`gcode.parser._Line`, listed under this name
        in ``gcode.parser._STATEMENT_PARSERS``)
    """

    keyword: str
    syntax: str
    effect: str
    simulated: str
    parser: str


@dataclass(frozen=True)
class GCode:
    """One G code of a block: its number, effect and how it is simulated
    (``handler`` names the function of :mod:`gcode.motion` that applies it)."""

    code: int
    effect: str
    simulated: str
    handler: str


def _rows(parser: str, simulated: str, rows: list[tuple[str, str, str]]) -> list[Command]:
    return [Command(k, syntax, effect, simulated, parser) for k, syntax, effect in rows]


_STRUCTURE = [
    Command("DVAR", "$a, $b, $pts[n]", "declares variables (value 0)", MODELLED, "dvar"),
    Command("REPEAT", "count", "runs the lines up to END REPEAT count times", MODELLED, "repeat"),
    Command("ENDREPEAT", "", "closes REPEAT (also END REPEAT)", MODELLED, "close"),
    Command("WHILE", "condition [DO]", "runs the lines up to ENDWHILE while the condition holds",
            MODELLED, "if"),
    Command("ENDWHILE", "", "closes WHILE (also END WHILE)", MODELLED, "close"),
    Command("IF", "condition THEN", "runs the lines up to ELSEIF/ELSE/ENDIF if it holds",
            MODELLED, "if"),
    Command("ELSEIF", "condition THEN", "the next branch of IF", MODELLED, "if"),
    Command("ELSE", "", "the last branch of IF", MODELLED, "else"),
    Command("ENDIF", "", "closes IF (also END IF)", MODELLED, "close"),
    Command("FOR", "$v = start TO end [STEP step]", "runs the lines up to NEXT with $v = start, "
            "start + step … while not past end", MODELLED, "for"),
    Command("NEXT", "[$v]", "closes FOR", MODELLED, "next"),
    Command("DFS", "name", "defines a subroutine up to ENDDFS", MODELLED, "dfs"),
    Command("ENDDFS", "", "closes DFS (also END DFS)", MODELLED, "close"),
    Command("CALL", "name [P1 Q$x …]", "runs subroutine name with $p, $q … set", MODELLED,
            "call"),
    Command("DWELL", "seconds", "waits (in the time; beam-on time if the beam is on)",
            MODELLED, "dwell"),
    Command("FREERUN", "axis [velocity | STOP]", "an axis runs free at a velocity: recorded (a "
            "path axis X Y Z C keeps its position)", RECORDED, "freerun"),
]

_MODES = _rows("mode", MODELLED, [
    ("SECONDS", "", "feeds per second"), ("MINUTES", "", "feeds per minute"),
    ("METRIC", "", "lengths in mm"), ("ENGLISH", "", "lengths in inches (25.4 mm)"),
    ("ABSOLUTE", "", "positions absolute (G90)"),
    ("INCREMENTAL", "", "positions relative to the current one (G91)"),
    ("END", "[PROGRAM]", "ends the program; END REPEAT/WHILE/IF/DFS close blocks"),
]) + [Command("ENABLE", "axis …", "enables drives (any axis names)", IGNORED, "mode")]

_MOTION = _rows("block", MODELLED, [
    ("LINEAR", "axis words [F]", "feed move in a straight line (G1)"),
    ("RAPID", "axis words", "rapid move (G0)"),
    ("CW", "axis words I J [F]", "clockwise arc (G2)"),
    ("CCW", "axis words I J [F]", "counter-clockwise arc (G3)"),
])

_PSO = _rows("pso", MODELLED, [
    ("PSOCONTROL", "axis FIRE | ON | ARM | OFF | RESET", "the laser: FIRE/ON/ARM on, OFF/RESET "
     "off"),
    ("PSOPULSE", "axis TIME period on [CYCLES n]", "pulse timing (µs): the repetition rate"),
]) + _rows("pso", IGNORED, [
    ("PSOOUTPUT", "axis CONTROL pin mode | PULSE …", "routes the PSO output (no effect on the "
     "path)"),
    ("PSOTRACK", "axis INPUT … | RESET …", "selects the PSO tracking input"),
    ("PSOWINDOW", "axis n ON | OFF | RANGE …", "sets a PSO window"),
    ("PSODISTANCE", "axis FIXED d | ARRAY …", "sets the PSO firing distance"),
    ("PSOARRAY", "axis …", "loads the PSO array"),
])

_UNSIMULATED = _rows("unsimulated", REFUSED, [
    (k, "axis …", "moves axes in a way tipgeo cannot simulate")
    for k in ("HOME", "MOVEABS", "MOVEINC", "MOVETO", "INDEX", "CAMSYNC", "GEAR", "SCAN",
              "OSCILLATE", "HOMEASYNC")])

_NO_MOTION = _rows("no_motion", RECORDED, [
    ("VELOCITY", "ON | OFF", "velocity blending (corner speed kept between moves)"),
    ("ROUNDING", "ON | OFF", "corner rounding"),
    ("CRITICAL", "START | END", "critical section (runs without interruption)"),
    ("WAIT", "MODE … | MOVEDONE axes | (condition) timeout",
     "waits for a condition (motion done, in position, a mode)"),
    ("FILEOPEN", '"file", mode', "opens a file"), ("FILECLOSE", "[handle]", "closes a file"),
    ("FILEWRITE", "handle | \"file\", values …", "writes a file"),
    ("FILEREAD", "handle, …", "reads a file"), ("FILEPRINT", "handle, …", "writes a file"),
    ("FILEDELETE", '"file"', "deletes a file"), ("FILEEXISTS", '"file"', "tests a file"),
    ("FILEPOS", "handle, n", "moves a file pointer"),
    ("FILEREADLINE", "handle, …", "reads a file"),
    ("FILEWRITELINE", "handle, …", "writes a file"),
    ("FILEAPPEND", '"file"', "opens a file for appending"),
    ("FILERENAME", '"old", "new"', "renames a file"),
    ("MSGDISPLAY", "n, values …", "shows a message"), ("MSGCLEAR", "n", "clears messages"),
    ("MSGBOX", "…", "shows a box"), ("MSGLAMP", "n, colour, \"text\"", "sets a lamp"),
    ("MSGSHOW", "…", "shows a message"), ("MSGHIDE", "…", "hides messages"),
    ("DISPLAY", "…", "shows a message"), ("FORMAT", "…", "formats a string"),
    ("STRCOPY", "…", "copies a string"), ("STRFORMAT", "…", "formats a string"),
    ("STRINSERT", "…", "edits a string"), ("STRDELETE", "…", "edits a string"),
    ("STRUPR", "…", "edits a string"), ("STRLWR", "…", "edits a string"),
    ("STRTONUM", "…", "converts a string"), ("NUMTOSTR", "…", "converts a number"),
    ("STRCONCAT", "…", "joins strings"), ("STRLEN", "…", "measures a string"),
    ("DBLTOSTR", "value, digits", "converts a number to a string"),
    ("SCOPETRIG", "…", "triggers the scope"), ("DATAACQ", "…", "data acquisition"),
    ("DISABLE", "axis …", "disables drives"), ("BRAKE", "axis ON | OFF", "sets a brake"),
    ("FAULTACK", "axis …", "acknowledges faults"),
    ("ACKNOWLEDGEALL", "", "acknowledges faults"),
    ("PLANE", "n", "selects a plane"), ("SETGAIN", "axis …", "sets servo gains"),
    ("PROGRAM", "[task] RUN | LOAD | BUFFEREDRUN | STEPINTO | PAUSE | STOP [\"file\"]",
     "A3200 task control: runs, loads, pauses or stops a program on a task (the other "
     "program is not simulated here)"),
    ("FARCALL", '"file"', "calls another program file and waits for it (not simulated here)"),
])

#: Every statement keyword, by keyword (upper case).
COMMANDS: dict[str, Command] = {
    c.keyword: c for c in _STRUCTURE + _MODES + _MOTION + _PSO + _UNSIMULATED + _NO_MOTION}

#: G codes of a block, by number.
G_CODES: dict[int, GCode] = {g.code: g for g in [
    GCode(0, "rapid move mode (RAPID)", MODELLED, "motion"),
    GCode(1, "line mode (LINEAR)", MODELLED, "motion"),
    GCode(2, "clockwise arc mode (CW)", MODELLED, "motion"),
    GCode(3, "counter-clockwise arc mode (CCW)", MODELLED, "motion"),
    GCode(4, "dwell P seconds", MODELLED, "dwell"),
    GCode(17, "XY plane (the only one simulated)", IGNORED, "nothing"),
    GCode(40, "cutter compensation off", MODELLED, "compensation"),
    GCode(41, "cutter compensation left", MODELLED, "compensation"),
    GCode(42, "cutter compensation right", MODELLED, "compensation"),
    GCode(44, "selects the compensation axes", IGNORED, "nothing"),
    GCode(66, "G66: a modal mode the simulation does not model (recorded, no motion)",
          RECORDED, "record"),
    GCode(70, "lengths in inches (ENGLISH)", MODELLED, "units"),
    GCode(71, "lengths in mm (METRIC)", MODELLED, "units"),
    GCode(75, "feeds per minute (MINUTES)", MODELLED, "time_base"),
    GCode(76, "feeds per second (SECONDS)", MODELLED, "time_base"),
    GCode(84, "G84 X Y F<deg>: turns the XY frame (+ counter-clockwise; no F: back to 0)",
          MODELLED, "rotation"),
    GCode(90, "absolute positions", MODELLED, "distance"),
    GCode(91, "incremental positions", MODELLED, "distance"),
    GCode(92, "position preset", MODELLED, "preset"),
    GCode(98, "as in Appendix C (no effect on the path)", IGNORED, "nothing"),
    GCode(108, "velocity blending on (VELOCITY ON)", RECORDED, "record"),
    GCode(109, "velocity blending off", RECORDED, "record"),
    GCode(359, "wait mode: no wait (G359)", RECORDED, "record"),
    GCode(360, "wait mode: auto (G360)", RECORDED, "record"),
    GCode(361, "wait mode: in position (G361)", RECORDED, "record"),
]}

#: Letters that start a word of a block, and what each sets.
WORD_LETTERS: dict[str, str] = {
    "G": "a G code (see G_CODES)", "X": "X position (mm)", "Y": "Y position (mm)",
    "Z": "Z position (mm)", "C": "C angle (deg)", "A": "A axis (not simulated)",
    "B": "B axis (not simulated)", "I": "arc centre X offset", "J": "arc centre Y offset",
    "K": "arc centre Z offset (ignored: XY arcs)", "F": "feed (length per time unit; G84: "
    "the angle, deg)", "E": "rotary feed (deg per time unit)", "T": "tool number (radius "
    "from the tool table)", "N": "line number (first word only)", "P": "G4's dwell time (s)",
}


def commands_by_parser(parser: str) -> dict[str, Command]:
    """The rows read by one statement parser, by keyword."""
    return {k: c for k, c in COMMANDS.items() if c.parser == parser}


def table_markdown() -> str:
    """The command table as Markdown (for the docs)."""
    lines = ["| command | arguments | effect | simulator |", "|---|---|---|---|"]
    for c in sorted(COMMANDS.values(), key=lambda c: c.keyword):
        syntax = c.syntax.replace("|", "\\|")
        lines.append(f"| `{c.keyword}` | {syntax} | {c.effect} | {c.simulated} |")
    lines += ["", "| G code | effect | simulator |", "|---|---|---|"]
    for g in G_CODES.values():
        lines.append(f"| `G{g.code}` | {g.effect} | {g.simulated} |")
    return "\n".join(lines)
