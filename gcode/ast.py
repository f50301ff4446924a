"""Syntax tree of the A3200 AeroBasic subset (see :mod:`gcode.parser`).

Every statement carries a :class:`Span` (1-based line and column of its first
character, and its source text) so later stages can report errors where they
happen. Expressions are a tiny tree evaluated by :mod:`gcode.expr`, never by
Python's ``eval``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Union

__all__ = ["Span", "Num", "Var", "Neg", "BinOp", "Compare", "Logic", "Not", "Expr", "Word",
           "Block", "Assign", "SysAssign", "DVar", "Mode", "Pso", "Repeat", "For", "While", "If",
           "Call", "Dwell", "NoMotion", "StatusRead", "StringAssign", "Sub", "Program", "Stmt",
           "StringTree", "IndexPart", "PsoArg"]


@dataclass(frozen=True)
class Span:
    """Where a statement starts (1-based) and its source text."""

    line: int
    col: int
    text: str


# -- expressions -----------------------------------------------------------------
@dataclass(frozen=True)
class Num:
    """A number literal."""

    value: float


@dataclass(frozen=True)
class Var:
    """A ``$variable``; ``name`` is lower-case, without the ``$``."""

    name: str


@dataclass(frozen=True)
class Neg:
    """Unary minus."""

    operand: Expr


@dataclass(frozen=True)
class BinOp:
    """``left op right`` with op one of ``+ - * /``."""

    op: str
    left: Expr
    right: Expr


@dataclass(frozen=True)
class Compare:
    """``left op right`` with op one of ``== <> < > <= >=`` (``=`` and ``!=``
    are read as ``==`` and ``<>``); 1 if true, else 0."""

    op: str
    left: Expr
    right: Expr


@dataclass(frozen=True)
class Logic:
    """``left AND right`` or ``left OR right`` (op upper-case); 1 or 0."""

    op: str
    left: Expr
    right: Expr


@dataclass(frozen=True)
class Not:
    """``NOT operand``: 1 if the operand is 0, else 0."""

    operand: Expr


Expr = Union[Num, Var, Neg, BinOp, Compare, Logic, Not]  # noqa: UP007 - a runtime alias

#: A string expression (:mod:`gcode.strings`): a tree of tuples.
StringTree = Union[  # noqa: UP007 - a runtime alias
    tuple[Literal["lit"], str], tuple[Literal["var"], str], tuple[Literal["num"], Expr],
    tuple[Literal["cat"], "StringTree", "StringTree"],
    tuple[Literal["call"], str, tuple["StringTree", ...]]]
#: A part of a system variable's index (:class:`SysAssign`): an expression for
#: ``[i]``, a string for ``.X`` or a glued ``.0``.
IndexPart = Union[Expr, str]  # noqa: UP007 - a runtime alias
#: An argument of a PSO command (:class:`Pso`): a keyword or an expression.
PsoArg = Union[str, Expr]  # noqa: UP007 - a runtime alias


# -- statements --------------------------------------------------------------------
@dataclass(frozen=True)
class Word:
    """A letter word: ``G1``, ``X$comp``, ``F 0.1``, ``I-$radius``.

    ``letter`` is upper-case; ``value`` is None for a bare axis name (as in
    ``G44 X Y``)."""

    letter: str
    value: Expr | None
    span: Span


@dataclass(frozen=True)
class Block:
    """One block of words, in source order, e.g. ``G01 G41 X$comp F $feed``;
    ``keywords`` holds motion keywords written as words (``LINEAR``,
    ``RAPID``, ``CW``, ``CCW``) in upper case."""

    words: tuple[Word, ...]
    keywords: tuple[str, ...]
    span: Span


@dataclass(frozen=True)
class Assign:
    """``$name = expr``."""

    name: str
    expr: Expr
    span: Span


@dataclass(frozen=True)
class SysAssign:
    """An assignment to a system variable or I/O: ``$DO[0].X = 1``,
    ``$AO[1].Y = 2.5``, ``$DO0.0 = 0``, ``$global[3] = $a``. No motion; the
    interpreter records the value set.

    ``name`` is the lower-case base name without ``$``; ``index`` the
    suffix parts in order: an expression for ``[i]``, a string for ``.X``
    (upper-case) or a glued ``.0`` (its text)."""

    name: str
    index: tuple[IndexPart, ...]
    expr: Expr
    span: Span


@dataclass(frozen=True)
class DVar:
    """``DVAR $a, $b, …`` — declares variables (lower-case names)."""

    names: tuple[str, ...]
    span: Span


@dataclass(frozen=True)
class Mode:
    """A keyword statement: ``SECONDS``, ``MINUTES``, ``METRIC``, ``ENGLISH``,
    ``ABSOLUTE``, ``INCREMENTAL``, ``ENABLE`` (with axis names in ``args``),
    ``END`` (end of program)."""

    keyword: str
    args: tuple[str, ...]
    span: Span


@dataclass(frozen=True)
class Pso:
    """A ``PSO*`` command: ``PSOPULSE X TIME 10 5 CYCLES 10000000`` →
    command ``PSOPULSE``, axis ``X``, args ``('TIME', Num(10), Num(5),
    'CYCLES', Num(1e7))``; ``PSOCONTROL X FIRE`` → args ``('FIRE',)``.
    Keyword arguments are upper-case strings, numbers are expressions."""

    command: str
    axis: str
    args: tuple[PsoArg, ...]
    span: Span


@dataclass(frozen=True)
class Repeat:
    """``REPEAT count … END REPEAT`` (or ``ENDREPEAT``)."""

    count: Expr
    body: tuple[Stmt, ...]
    span: Span


@dataclass(frozen=True)
class For:
    """``FOR $var = start TO end [STEP step]`` … ``NEXT [$var]``: the body
    runs with ``$var`` = start, start + step, … while it has not passed
    ``end`` (bounds and step evaluated once, at the start)."""

    var: str
    start: Expr
    end: Expr
    step: Expr | None
    body: tuple[Stmt, ...]
    span: Span


@dataclass(frozen=True)
class StatusRead:
    """``$x = AXISSTATUS(Z, DATAITEM_…)`` (or another controller status
    function): the value is known only on the machine, so the variable
    becomes unknown (using it later is an error) and the read is recorded."""

    name: str
    function: str
    span: Span


@dataclass(frozen=True)
class StringAssign:
    """``$s = "x = " + DBLTOSTR($x, 3)``: a string expression, evaluated by
    :mod:`gcode.strings` (``parts`` are its tokens after the ``=``)."""

    name: str
    parts: StringTree
    span: Span


@dataclass(frozen=True)
class While:
    """``WHILE cond [DO]`` … ``ENDWHILE`` (or ``END WHILE``)."""

    cond: Expr
    body: tuple[Stmt, ...]
    span: Span


@dataclass(frozen=True)
class If:
    """``IF cond THEN`` … ``ELSEIF cond THEN`` … ``ELSE`` … ``ENDIF``.

    ``branches`` are ``(cond, body)`` pairs in order; the ``ELSE`` branch
    has cond None."""

    branches: tuple[tuple[Expr | None, tuple[Stmt, ...]], ...]
    span: Span


@dataclass(frozen=True)
class Call:
    """``CALL name P1 Q$x``: runs subroutine ``name`` (upper-case); ``args``
    are ``(letter, expr)`` pairs, visible in the subroutine as ``$p``,
    ``$q`` …"""

    name: str
    args: tuple[tuple[str, Expr], ...]
    span: Span


@dataclass(frozen=True)
class Dwell:
    """``DWELL t`` or ``G4 P t``: wait ``t`` seconds."""

    seconds: Expr
    span: Span


@dataclass(frozen=True)
class NoMotion:
    """A statement that moves nothing the simulation follows: ``VELOCITY
    ON``, ``ROUNDING``, ``G359``, ``CRITICAL START``, ``FILECLOSE $h``,
    ``MSGDISPLAY …``, ``FREERUN`` of an axis outside X Y Z C, ``WAIT …``.
    ``keyword`` is upper-case (with its mode word: ``VELOCITY ON``), ``what``
    says what it does."""

    keyword: str
    what: str
    span: Span


@dataclass(frozen=True)
class Sub:
    """``DFS name`` … ``ENDDFS``: a subroutine (name upper-case)."""

    name: str
    body: tuple[Stmt, ...]
    span: Span


Stmt = Union[Block, Assign, SysAssign, DVar, Mode, Pso, Repeat, For, While, If, Call,  # noqa: UP007
             Dwell, NoMotion, StatusRead, StringAssign]


@dataclass(frozen=True)
class FunctionMacro:
    """A function-like ``#define NAME(a, b) text`` macro: its parameter names
    and replacement text (the parameters appear in it as plain names)."""

    params: tuple[str, ...]
    body: str


@dataclass(frozen=True)
class Program:
    """A parsed program: statements in order, warnings of skipped text
    (lenient mode), subroutines (``DFS``, wherever they were written) and
    ``#define`` macros (name → replacement text, or a :class:`FunctionMacro`)."""

    body: tuple[Stmt, ...]
    warnings: tuple[str, ...] = ()
    subroutines: tuple[Sub, ...] = ()
    macros: tuple[tuple[str, str | FunctionMacro], ...] = ()
