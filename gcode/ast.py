"""Syntax tree of the A3200 AeroBasic subset (see :mod:`gcode.parser`).

Every statement carries a :class:`Span` (1-based line and column of its first
character, and its source text) so later stages can report errors where they
happen. Expressions are a tiny tree evaluated by :mod:`gcode.expr`, never by
Python's ``eval``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

__all__ = ["Span", "Num", "Var", "Neg", "BinOp", "Expr", "Word", "Block", "Assign", "DVar",
           "Mode", "Pso", "Repeat", "Program", "Stmt"]


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


Expr = Union[Num, Var, Neg, BinOp]  # noqa: UP007 - a runtime alias (3.10)


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
    args: tuple
    span: Span


@dataclass(frozen=True)
class Repeat:
    """``REPEAT count … END REPEAT`` (or ``ENDREPEAT``)."""

    count: Expr
    body: tuple
    span: Span


Stmt = Union[Block, Assign, DVar, Mode, Pso, Repeat]  # noqa: UP007


@dataclass(frozen=True)
class Program:
    """A parsed program: statements in order, and warnings of skipped text
    (lenient mode)."""

    body: tuple
    warnings: tuple[str, ...] = ()
