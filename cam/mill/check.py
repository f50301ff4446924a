"""The checks a milling program passes before it is written: read back from
its text by the simulator's reader (:func:`cam.mill.read_gcode`: only the
words it can simulate), then held against the machine and the tool — every
programmed point plus the work offset inside the travels, every feed inside
the feed range, the spindle speed inside the spindle's range, the tool it
calls the tool it was planned for.

Program frame and units: :mod:`cam.mill.machine` (mm, feeds mm/min, rpm).
"""

from __future__ import annotations

import numpy as np

from ..machine import AxisLimit, CamError
from .machine import EndMill, MillMachine
from .simulate import GCodeMoves, read_gcode

__all__ = ["check_program"]


def check_program(text: str, machine: MillMachine, tool: EndMill) -> GCodeMoves:
    """The moves of the G-code ``text`` once it has passed every check (see
    the module docstring).

    Raises
    ------
    CamError
        Naming the line, the axis, word or parameter, its value and the
        limit: a word the reader cannot simulate, a point outside a travel, a
        feed or a spindle speed outside the machine's range, another tool.
    """
    moves = read_gcode(text)
    _check_tool(moves, tool)
    _check_spindle(moves, machine)
    _check_feeds(moves, machine)
    _check_travels(moves, machine)
    return moves


def _line(moves: GCodeMoves, k: int) -> str:
    """``line N: `` of move ``k`` (empty when the lines are not known)."""
    return "" if moves.line is None else f"line {int(moves.line[k])}: "


def _check_tool(moves: GCodeMoves, tool: EndMill) -> None:
    if moves.tool is not None and moves.tool != tool.number:
        raise CamError(f"the program calls T{moves.tool}; the tool planned for is "
                       f"T{tool.number} ({tool.describe()})")


def _check_spindle(moves: GCodeMoves, machine: MillMachine) -> None:
    if moves.spindle_rpm is None:
        raise CamError("the program never sets the spindle speed (no S word); the machine "
                       f"needs {machine.spindle_rpm_min:g}–{machine.spindle_rpm_max:g} rpm")
    machine.check_spindle(moves.spindle_rpm)


def _check_feeds(moves: GCodeMoves, machine: MillMachine) -> None:
    fed = np.flatnonzero(~moves.rapid)
    bad = fed[(moves.feed[fed] < machine.feed_min) | (moves.feed[fed] > machine.feed_max)]
    if len(bad):
        k = int(bad[0])
        raise CamError(f"{_line(moves, k)}F = {moves.feed[k]:g} mm/min is outside the "
                       f"machine's feed range [{machine.feed_min:g}, {machine.feed_max:g}] "
                       "mm/min")


def _check_travels(moves: GCodeMoves, machine: MillMachine) -> None:
    """Every programmed point plus the work offset inside the travel of its
    axis: the first move's start and every move's end (each move starts
    where the one before ended; a G28 return ends at the machine's home,
    inside its travel by definition), the first outside named by its line."""
    from tipgeo.tolerances import tol

    home = moves.home if moves.home is not None else np.zeros(len(moves.start), bool)
    pts = np.concatenate([moves.start[:1], moves.end])
    keep = np.concatenate([[True], ~home])
    which = np.concatenate([[0], np.arange(len(moves.end))])      # the move of each point
    slack = tol.cam.mill_travel
    bad = np.zeros(len(pts), bool)
    for k, ax in enumerate("xyz"):
        lim: AxisLimit = getattr(machine, ax)
        val = pts[:, k] + machine.work_offset[k]
        bad |= keep & np.isfinite(val) & ((val < lim.lo - slack) | (val > lim.hi + slack))
    if not bad.any():
        return
    i = int(np.flatnonzero(bad)[0])
    for k, ax in enumerate("xyz"):
        lim = getattr(machine, ax)
        off = machine.work_offset[k]
        v = pts[i, k] + off
        if not lim.lo - slack <= v <= lim.hi + slack:
            raise CamError(f"{_line(moves, int(which[i]))}axis {ax.upper()} = {v:.4f} mm "
                           f"(program {pts[i, k]:.4f} mm + work offset {off:g} mm) is outside "
                           f"its travel [{lim.lo:g}, {lim.hi:g}] mm")
