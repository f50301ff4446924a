"""Material-removal simulator for three-axis milling with ball, bull-nose and
flat end mills: G-code → the
milled tip, and its comparison with the CAD tip.

Frames and units: :mod:`cam.mill.machine` (program frame of the G-code,
cannula frame of the tip: turned by the clocking angle about z; mm, rad
inside; deviations µm, angles degrees in reports).

How it works (a dexel model)
----------------------------
The program is read back from its text (:func:`read_gcode`: G00/G01 in G90
G21, the words the posts write; anything else is refused with its line). A
tool with its shank removes, in each vertical column, everything above the
lowest point of the tool it swept, so the milled height of a column (a dexel)
is min(stock top, lowest point over the column of every move's swept tool):
exact for each move (:mod:`cam.mill.dexel`: the lower end of a capsule for a
ball, closed form for a flat end, a convex 1-D minimum for a bull nose), for
every move that can reach the stock — no sampling along the path. Moves are
binned in 50 µm tiles, sorted by a lower bound of their height over the tile,
so each column visits only the moves whose footprint meets its tile and stops
once no further move can cut lower.

Columns are evaluated on a grid (default 1 µm across the passes, where the
scallops are, 20 µm along them, where the surface is smooth) over the annulus
for the deviation map, and on a polar grid for the
milled :class:`tipgeo.Tip` (watertight, faces labelled with the CAD face
that lies under them, walls ``outer``/``inner``, ``base``), so the edge and
angle analysis runs on it like on any tip.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tipgeo.arrays import BoolArray, FloatArray, IntArray
from tipgeo.plot import styled
from tipgeo.tolerances import tol

from ..machine import CamError
from .machine import EndMill
from .toolpath import MillSetup, MillToolpath, ProgressFn, cad_height, to_cannula, to_program

if TYPE_CHECKING:
    from tipgeo.spec import TipSpec
    from tipgeo.tip import Tip

__all__ = ["GCodeMoves", "read_gcode", "MilledTip", "simulate_mill", "sweep_heights",
           "compare_milled", "plot_deviation", "plot_toolpath"]

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_ALLOWED_G = {0, 1, 17, 21, 28, 40, 43, 49, 54, 80, 90, 91, 94}
_ALLOWED_M = {3, 5, 6, 8, 9, 30}

#: How far (mm) above the higher of its start and the program zero a G28
#: return is taken straight up: clear of everything.
G28_LIFT = 100.0


@dataclass
class GCodeMoves:
    """Straight moves read from a program (program frame, mm; feeds mm/min).

    start, end : (n, 3) float; rapid : (n,) bool; feed : (n,) float (NaN for
    rapids); tool : int or None; spindle_rpm : float or None; lines : the
    program's line count; line : (n,) int, the line of each move (1-based);
    home : (n,) bool, the G28 returns (taken straight up, their end Z
    :data:`G28_LIFT` above the start: not a programmed point)
    """

    start: FloatArray
    end: FloatArray
    rapid: BoolArray
    feed: FloatArray
    tool: int | None
    spindle_rpm: float | None
    lines: int
    line: IntArray | None = None
    home: BoolArray | None = None

    def cycle_time(self, rapid_feed: float) -> float:
        """Seconds: feed moves at their F, rapids at ``rapid_feed`` (mm/min);
        acceleration and tool change not counted."""
        length = np.linalg.norm(self.end - self.start, axis=1)
        f = np.where(self.rapid, rapid_feed, self.feed)
        return float(np.sum(length / f) * 60.0)

    def summary(self, rapid_feed: float) -> dict[str, Any]:
        """Lines, moves, feed and rapid path lengths (mm), the cycle time (s)
        at ``rapid_feed`` (mm/min) for the rapids, the tool and the spindle
        speed (rpm)."""
        length = np.linalg.norm(self.end - self.start, axis=1)
        return {"lines": self.lines, "moves": int(len(self.start)),
                "feed_length_mm": float(length[~self.rapid].sum()),
                "rapid_length_mm": float(length[self.rapid].sum()),
                "cycle_time_s": self.cycle_time(rapid_feed), "tool": self.tool,
                "spindle_rpm": self.spindle_rpm}


@dataclass
class _Reader:
    """The G-code reader's modal state and the moves read so far (program
    frame, mm); :meth:`block` reads one line's words through the word table
    :data:`_WORDS`."""

    pos: list[float | None] = field(default_factory=lambda: [None, None, None])
    mode: int = 0
    feed: float = math.nan
    tool: int | None = None
    rpm: float | None = None
    absolute: bool = True
    n: int = 0
    target: list[float | None] = field(default_factory=list)
    moved: bool = False
    home: bool = False
    starts: list[list[float | None]] = field(default_factory=list)
    ends: list[list[float | None]] = field(default_factory=list)
    rapids: list[bool] = field(default_factory=list)
    feeds: list[float] = field(default_factory=list)
    homes: list[bool] = field(default_factory=list)
    at: list[int] = field(default_factory=list)

    def block(self, n: int, words: list[tuple[str, float]]) -> None:
        """Read the words of line ``n`` and record its move, if any."""
        self.n, self.target, self.moved, self.home = n, list(self.pos), False, False
        for a, val in words:
            handler = _WORDS.get(a)
            if handler is None:
                raise CamError(f"line {n}: word {a} is not supported by the simulator")
            handler(self, a, val)
        if self.home:
            if self.pos[2] is None:
                return
            self.target, self.moved = [self.pos[0], self.pos[1], math.inf], True
        if self.moved:
            self._record()

    def _record(self) -> None:
        if None not in self.pos and None not in self.target:
            rapid = self.mode == 0 or self.home
            if not rapid and not math.isfinite(self.feed):
                raise CamError(f"line {self.n}: a G01 move with no feed yet")
            self.starts.append(list(self.pos))
            self.ends.append(list(self.target))
            self.rapids.append(rapid)
            self.feeds.append(math.nan if rapid else self.feed)
            self.homes.append(self.home)
            self.at.append(self.n)
        self.pos = self.target

    def moves(self) -> GCodeMoves:
        """The moves read (a CamError when there is none)."""
        if not self.starts:
            raise CamError("the program has no move")
        st = np.array(self.starts, float)
        en = np.array(self.ends, float)
        up = ~np.isfinite(en[:, 2])
        en[up, 2] = np.maximum(st[up, 2], 0.0) + G28_LIFT   # straight up, clear of everything
        return GCodeMoves(st, en, np.array(self.rapids, bool), np.array(self.feeds, float),
                          self.tool, self.rpm, self.n, line=np.array(self.at, int),
                          home=np.array(self.homes, bool))


def _word_g(rd: _Reader, a: str, val: float) -> None:
    g = int(round(val))
    if g not in _ALLOWED_G or abs(val - g) > tol.cam.mill_word_integer:
        allowed = ", ".join(f"G{x:02d}" for x in sorted(_ALLOWED_G))
        raise CamError(f"line {rd.n}: G{val:g} is not supported by the simulator "
                       f"(allowed: {allowed})")
    if g in (0, 1):
        rd.mode = g
    elif g in (90, 91):
        rd.absolute = g == 90
    elif g == 28:
        rd.home = True


def _word_m(rd: _Reader, a: str, val: float) -> None:
    if int(round(val)) not in _ALLOWED_M:
        raise CamError(f"line {rd.n}: M{val:g} is not supported by the simulator")


def _word_f(rd: _Reader, a: str, val: float) -> None:
    if not val > 0:
        raise CamError(f"line {rd.n}: F = {val:g} must be positive (mm/min)")
    rd.feed = val


def _word_s(rd: _Reader, a: str, val: float) -> None:
    rd.rpm = val


def _word_t(rd: _Reader, a: str, val: float) -> None:
    rd.tool = int(val)


def _word_axis(rd: _Reader, a: str, val: float) -> None:
    if rd.home:
        return
    k = "XYZ".index(a)
    if rd.absolute:
        rd.target[k] = val
    else:
        p = rd.pos[k]
        if p is None:
            raise CamError(f"line {rd.n}: incremental {a} before the position is known")
        rd.target[k] = p + val
    rd.moved = True


def _word_ignored(rd: _Reader, a: str, val: float) -> None:
    """H (length offset), N (line number), D, P, O: nothing to simulate."""


#: The reader's word table: letter → handler of (reader, letter, value).
_WORDS: dict[str, Callable[[_Reader, str, float], None]] = {
    "G": _word_g, "M": _word_m, "F": _word_f, "S": _word_s, "T": _word_t,
    "X": _word_axis, "Y": _word_axis, "Z": _word_axis,
    **{c: _word_ignored for c in "HNDPO"}}


def _words(n: int, raw: str) -> list[tuple[str, float]]:
    """The (letter, value) words of program line ``n`` (comments, ``%`` and
    the ``O`` number dropped); a CamError for what is not a word."""
    line = raw.strip().upper()
    if "(" in line or ")" in line:
        if line.count("(") != line.count(")") or re.search(r"\([^)]*\(", line):
            raise CamError(f"line {n}: unbalanced or nested comment: {raw.strip()[:60]!r}")
        line = re.sub(r"\([^)]*\)", " ", line)
    line = line.split(";")[0].strip()
    if not line or line == "%":
        return []
    if line.startswith("O") and re.fullmatch(r"O\d+", line.split()[0]):
        line = " ".join(line.split()[1:])
    rest = _WORD.sub(" ", line).strip()
    if rest:
        raise CamError(f"line {n}: cannot read {rest[:30]!r} in {raw.strip()[:60]!r}")
    return [(a, float(b)) for a, b in _WORD.findall(line)]


def read_gcode(text: str) -> GCodeMoves:
    """The straight moves of a G-code program (Haas/Fanuc subset: G00, G01,
    G17 G21 G28 G40 G43 G49 G54 G80 G90 G91 G94, T, S, F, H, M03 M05 M06 M08
    M09 M30, comments in parentheses, ``%`` and ``O`` lines; program frame,
    mm, feeds mm/min). G28 returns Z home (the move is taken straight up).
    Anything else (G20 inch programs too) is a CamError naming the line."""
    rd = _Reader()
    for n, raw in enumerate(text.splitlines(), 1):
        rd.n = n
        words = _words(n, raw)
        if words:
            rd.block(n, words)
    return rd.moves()


class _Dexels:
    """The moves that can reach the stock, tiled for the column kernel
    (:mod:`cam.mill.dexel`): tool tips A → B (program frame, mm), over the
    tiles that meet r_i ≤ r ≤ r_o + R, all the tool reaches outside the bore
    (columns elsewhere read the stock top)."""

    #: Side (mm) of the square tiles the moves are binned in.
    TILE = 0.05

    def __init__(self, moves: GCodeMoves, tool: EndMill, z_top: float, r_i: float,
                 r_o: float) -> None:
        from .dexel import tile_moves

        R, r = tool.radius, tool.corner
        reach = r_o + R
        a, b = moves.start, moves.end
        lowz = np.minimum(a[:, 2], b[:, 2])
        d = b[:, :2] - a[:, :2]
        L2 = np.sum(d * d, axis=1)
        t = np.clip(-np.sum(a[:, :2] * d, axis=1) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
        closest = np.linalg.norm(a[:, :2] + t[:, None] * d, axis=1)
        use = (lowz < z_top) & (closest < reach)
        if not use.any():
            raise CamError("no move of the program reaches the stock")
        self.A = np.ascontiguousarray(a[use])
        self.B = np.ascontiguousarray(b[use])
        self.R, self.r, self.z_top = R, r, z_top
        self.tile = self.TILE
        self.x0 = self.y0 = -reach
        self.n = int(math.ceil(2 * reach / self.tile)) + 1
        c = self.x0 + (np.arange(self.n) + 0.5) * self.tile
        rc = np.hypot(*np.meshgrid(c, c)).ravel()
        half = self.tile / math.sqrt(2.0)
        need = (rc + half >= r_i) & (rc - half <= reach)
        self.start, self.idx, self.bound = tile_moves(self.A, self.B, R, r, self.x0, self.y0,
                                                      self.tile, self.n, self.n, need)

    def heights(self, xy: FloatArray) -> FloatArray:
        """Milled heights (mm) of columns at program-frame points (m, 2)."""
        from .dexel import column_heights

        xy = np.ascontiguousarray(xy, dtype=float)
        out: FloatArray = column_heights(xy[:, 0].copy(), xy[:, 1].copy(), self.A, self.B,
                                         self.R, self.r, self.z_top, self.start, self.idx,
                                         self.bound, self.x0, self.y0, self.tile, self.n, self.n)
        return out


def sweep_heights(gcode: str, tool: EndMill, xy: FloatArray, *, z_top: float) -> FloatArray:
    """Milled heights (mm, program frame) of the columns at ``xy`` (m, 2) of a
    block faced at ``z_top`` after the G-code program ``gcode`` with end mill
    ``tool``: the dexel sweep of :func:`simulate_mill` without a tip."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    moves = read_gcode(gcode)
    r_o = float(np.hypot(xy[:, 0], xy[:, 1]).max()) + tol.cam.mill_reach
    return _Dexels(moves, tool, z_top, 0.0, r_o).heights(xy)


@dataclass
class MilledTip:
    """What :func:`simulate_mill` made (mm; program frame for the grid).

    tip : Tip — the milled tip (cannula frame, labelled, watertight)
    x, y : (nx,), (ny,) — grid coordinates (program frame); height : (ny, nx)
    milled z (NaN off the annulus); cad : (ny, nx) CAD z; nz : (ny, nx) CAD
    normal's z component; moves : GCodeMoves; clocking : rad
    """

    tip: Tip
    x: FloatArray
    y: FloatArray
    height: FloatArray
    cad: FloatArray
    nz: FloatArray
    moves: GCodeMoves
    clocking: float
    radius: float
    dexels: _Dexels = field(repr=False)
    normals: FloatArray = field(repr=False)
    z_top: float = 0.0

    def deviation(self) -> FloatArray:
        """(ny, nx) signed normal deviation milled − CAD (mm; + material left)."""
        out: FloatArray = (self.height - self.cad) * self.nz
        return out

    def heights_at(self, spec: TipSpec, p_cannula_xy: FloatArray) -> FloatArray:
        """Milled heights (mm) at cannula-frame points (m, 2)."""
        return _heights_at(self.dexels, self.clocking, p_cannula_xy)


def _heights_at(dexels: _Dexels, clocking: float, p_cannula_xy: FloatArray) -> FloatArray:
    """Milled heights (mm) at cannula-frame points (m, 2) of the moves
    ``dexels`` in a set-up clocked by ``clocking`` (rad)."""
    xy = to_program(np.column_stack([p_cannula_xy, np.zeros(len(p_cannula_xy))]),
                    clocking)[:, :2]
    return dexels.heights(xy)


def simulate_mill(gcode: str, spec: TipSpec, *, tool: EndMill, setup: MillSetup,
                  cell_um: tuple[float, float] = (20.0, 1.0), rings: int = 13,
                  around: int = 1440, progress: ProgressFn | None = None) -> MilledTip:
    """Mill the stock of ``spec`` (the tube faced at ``setup.z_top``) with the
    G-code ``gcode`` and end mill ``tool`` (ball, bull nose or flat) in set-up
    ``setup``.

    Parameters
    ----------
    cell_um : (along X, across Y) µm — the deviation grid (program frame)
    rings, around : the milled tip's polar grid (radii × angles)

    Returns
    -------
    MilledTip

    Raises
    ------
    CamError
        A program it cannot read.
    """
    from tipgeo import progress as pg

    from .toolpath import progress_say

    say = progress_say(progress)
    moves = read_gcode(gcode)
    if moves.tool is not None and moves.tool != tool.number:
        raise CamError(f"the program calls T{moves.tool}; the tool given is T{tool.number}")
    can = spec.cannula
    R = tool.radius
    if not all(0.1 <= float(c) <= 50.0 for c in cell_um):
        raise CamError(f"cell_um = {tuple(cell_um)}: each between 0.1 and 50 µm")
    dx, dy = (float(c) * 1e-3 for c in cell_um)
    with pg.stage("mill: simulate (tiling the moves)"):
        dex = _Dexels(moves, tool, setup.z_top, can.r_i, can.r_o)
    say(f"simulate: {len(dex.A)} moves reach the stock")
    x = np.arange(-can.r_o, can.r_o + dx / 2, dx)
    y = np.arange(-can.r_o, can.r_o + dy / 2, dy)
    X, Y = np.meshgrid(x, y)
    rr = np.hypot(X, Y)
    on = (rr >= can.r_i) & (rr <= can.r_o)
    pc = to_cannula(np.column_stack([X[on], Y[on], np.zeros(on.sum())]), setup.clocking)
    zc, nc = cad_height(spec, pc[:, 0], pc[:, 1], normals=True)
    say(f"simulate: {on.sum()} columns")
    q = np.column_stack([X[on], Y[on]])
    h = np.empty(len(q))
    chunks = np.array_split(np.arange(len(q)), max(1, min(20, len(q) // 2000)))
    with pg.bar(len(chunks), "mill: simulate (dexel columns)", unit="chunk") as bar:
        for idx in chunks:
            h[idx] = dex.heights(q[idx])
            bar.update()
    H = np.full(X.shape, np.nan)
    C = np.full(X.shape, np.nan)
    NZ = np.full(X.shape, np.nan)
    H[on], C[on], NZ[on] = h, zc, nc[:, 2]
    N = np.full(X.shape + (3,), np.nan)
    N[on] = nc
    with pg.stage("mill: simulate (milled tip mesh)"):
        tip = _milled_tip(dex, setup.clocking, spec, rings, around)
    return MilledTip(tip, x, y, H, C, NZ, moves, setup.clocking, R, dexels=dex,
                     z_top=setup.z_top, normals=N)


def _milled_tip(dex: _Dexels, clocking: float, spec: TipSpec, rings: int,
                around: int) -> Tip:
    """The milled tip (cannula frame, mm): the milled heights of ``dex`` on
    a polar grid of ``rings`` radii × ``around`` angles over the wall, closed
    by the walls and a base; each top triangle labelled with the CAD face
    under it."""
    from tipgeo import Tip
    from tipgeo.edges import lowest_cut

    can = spec.cannula
    r = np.linspace(can.r_i, can.r_o, rings)
    g = np.linspace(0.0, 2 * math.pi, around, endpoint=False)
    rr, gg = np.meshgrid(r, g, indexing="ij")          # (rings, around)
    pxy = np.column_stack([(rr * np.cos(gg)).ravel(), (rr * np.sin(gg)).ravel()])
    z = _heights_at(dex, clocking, pxy)
    zb = min(-1.0, float(z.min()) - 1.0)
    top = np.column_stack([pxy, z])
    nt = rings * around
    ob = np.column_stack([can.r_o * np.cos(g), can.r_o * np.sin(g), np.full(around, zb)])
    ib = np.column_stack([can.r_i * np.cos(g), can.r_i * np.sin(g), np.full(around, zb)])
    verts = np.concatenate([top, ob, ib])
    j = np.arange(around)
    j1 = (j + 1) % around

    def vid(i: int, jj: IntArray) -> IntArray:
        return i * around + jj

    faces: list[IntArray] = []
    labels: list[IntArray] = []
    # the CAD face under each ring band (between rings i, i+1) at mid-angle
    names = ["outer", "inner", "base"]
    gm = g + math.pi / around
    for i in range(rings - 1):
        _, face, _ = lowest_cut(spec.cutters, gm, 0.5 * (r[i] + r[i + 1]), can)
        lab = []
        for f in face:
            f = str(f)
            if f not in names:
                names.append(f)
            lab.append(names.index(f))
        a, b, c, d = vid(i, j), vid(i + 1, j), vid(i + 1, j1), vid(i, j1)
        faces += [np.column_stack([a, b, c]), np.column_stack([a, c, d])]
        labels += [np.array(lab), np.array(lab)]
    to_, bo = vid(rings - 1, j), nt + j
    to1, bo1 = vid(rings - 1, j1), nt + j1
    faces += [np.column_stack([to_, bo, bo1]), np.column_stack([to_, bo1, to1])]
    labels += [np.zeros(around, int)] * 2
    ti, bi = vid(0, j), nt + around + j
    ti1, bi1 = vid(0, j1), nt + around + j1
    faces += [np.column_stack([ti, bi1, bi]), np.column_stack([ti, ti1, bi1])]
    labels += [np.ones(around, int)] * 2
    faces += [np.column_stack([bi, bo1, bo]), np.column_stack([bi, bi1, bo1])]
    labels += [np.full(around, 2)] * 2
    tip = Tip(verts, np.concatenate(faces), np.concatenate(labels), tuple(names),
              spec=None, tolerance=None, segments=around, source="mill simulation")
    if tip.volume < 0:
        tip.faces = tip.faces[:, ::-1].copy()
    tip.meta["milled_from"] = spec.name
    return tip


def compare_milled(res: MilledTip, spec: TipSpec, *, scallop: float, stepover: float,
                   margin: float | None = None, kink_margin_deg: float = 6.0,
                   heel_margin_deg: float = 5.0) -> dict[str, Any]:
    """Milled versus CAD (report units: µm, degrees).

    Deviation (signed, normal to the CAD surface, + = material left) over the
    cut face *away from the edge*: the annulus r_i + m ≤ r ≤ r_o − m, m =
    ``margin`` (default ``tol.cam.mill_edge_margin``); the scallop measured is
    its largest value, the gouge its most negative.

    λ, θ and α of both edges at the exact CAD edge points, against the exact
    CAD angles. The milled edge's tangent is the CAD tangent with z′ raised by
    the slope of the edge's deviation along the rim, and its rake-face normal
    the CAD normal tilted by the deviation's gradient over a band of the wall
    (one step-over deep, at most 0.8 of the wall); both fits are Hann-weighted
    over four scallop periods along the rim (P = step-over / |sin β|, β
    between the rim and the passes), so the scallops' ripple, which swings
    the raw edge's local λ by several degrees (±10° at the three-plane tip's
    heel at 2 µm), averages out (:func:`_edge_deviation_slope`). The mesh
    path (:func:`tipgeo.angles.analyze`, a Fourier fit of the milled edge's
    z(γ) against the CAD mesh's) is reported beside it
    (``lambda_mesh_fit_max_diff_deg``): its five harmonics follow part of the
    ripple (0.54–0.57° at the three-plane tip's heel at 2 µm, where the
    passes cross the rim at 30° and the ripple's period is longest).
    Compared along γ ∈ [``heel_margin_deg``, 360° − ``heel_margin_deg``] (at
    the heel λ climbs from 0 by several degrees per degree of γ), at the same
    cannula-frame γ, away from the rim corners (kinks between faces) by
    ``kink_margin_deg`` and by as much as keeps the fitting band the ridge
    margin from a ridge ((step-over + ``tol.cam.mill_ridge_margin``)/r_i);
    the windows along the rim stop the ridge margin short of a rim corner.
    """
    from tipgeo.angles import analyze, edge_angles

    m = tol.cam.mill_edge_margin if margin is None else margin
    mr = tol.cam.mill_ridge_margin
    can = spec.cannula
    X, Y = np.meshgrid(res.x, res.y)
    rr = np.hypot(X, Y)
    region = (rr >= can.r_i + m) & (rr <= can.r_o - m) & ~_near_ridges(res, mr)
    dev = res.deviation()
    dv = dev[region]
    out = {"region": f"annulus r_i + {m * 1e3:g} µm ≤ r ≤ r_o − {m * 1e3:g} µm, "
                     f"{mr * 1e3:g} µm from ridges between faces ({region.sum()} columns)",
           "scallop_target_um": scallop * 1e3,
           "scallop_measured_um": float(np.nanmax(dv) * 1e3),
           "deviation_p99_um": float(np.nanpercentile(dv, 99) * 1e3),
           "deviation_mean_um": float(np.nanmean(dv) * 1e3),
           "gouge_um": float(max(0.0, -np.nanmin(dv)) * 1e3),
           "deviation_all_max_um": float(np.nanmax(dev) * 1e3),
           "deviation_all_min_um": float(np.nanmin(dev) * 1e3)}
    from tipgeo import build_tip

    rc = analyze(spec, method="exact")
    rcm = analyze(build_tip(spec), method="mesh")
    rm = analyze(res.tip, method="mesh", radii=(can.r_o, can.r_i), name="milled")
    steps = math.floor((360.0 - 2.0 * heel_margin_deg) / 0.5 + tol.cam.mill_grid)
    g = np.radians(heel_margin_deg + 0.5 * np.arange(steps + 1))
    kinks = [k.gamma for w in (rc.outer, rc.inner) for k in w.edge.kinks]
    # away from the rim corners: by kink_margin_deg, and so far that the
    # normal's fitting window (a step-over each side) keeps the ridge margin
    kink_margin = max(math.radians(kink_margin_deg), (stepover + mr) / can.r_i)
    if kinks:
        dist = np.min(np.abs(np.angle(np.exp(1j * (g[:, None] - np.array(kinks)[None])))),
                      axis=1)
        g = g[dist > kink_margin]
    heel = rc.outer.edge.heel
    # the milled tip finds its own heel (its lowest edge vertex, moved by the
    # scallops); compare at the same cannula-frame γ
    shift = heel[0] - rm.outer.edge.heel[0]
    angles = {}
    for wall, radius in (("outer", can.r_o), ("inner", can.r_i)):
        cad = getattr(rc, wall).at(g)
        cad_mesh = getattr(rcm, wall).at(np.mod(g + heel[0] - rcm.outer.edge.heel[0],
                                                2 * math.pi))
        mesh = getattr(rm, wall).at(np.mod(g + shift, 2 * math.pi))
        # windowed plane fit behind each edge point (cannula frame)
        ga = g + heel[0]
        side = -1.0 if wall == "outer" else 1.0
        length = _window(res, ga, radius, stepover, np.asarray(kinks) + heel[0], mr)
        n_fit = _fit_normals(res, spec, ga, radius, side, length,
                             min(stepover, 0.8 * can.wall))
        # the milled edge's tangent: the exact CAD z′ plus the slope of the
        # edge's deviation averaged over whole scallops
        slope = _edge_deviation_slope(res, spec, ga, radius, side, length)
        t = np.stack([-radius * np.sin(g), radius * np.cos(g), cad["dz"] + radius * slope], 1)
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        # normals into the analysis frame (γ from the heel)
        c, s = math.cos(-heel[0]), math.sin(-heel[0])
        n_an = np.column_stack([c * n_fit[:, 0] - s * n_fit[:, 1],
                                s * n_fit[:, 0] + c * n_fit[:, 1], n_fit[:, 2]])
        lam, theta, alpha = edge_angles(g, t, n_an, wall)
        angles[wall] = {
            "lambda_max_diff_deg": float(np.degrees(np.nanmax(np.abs(lam - cad["lambda"])))),
            "lambda_worst_gamma_deg": float(np.degrees(g[np.nanargmax(np.abs(
                lam - cad["lambda"]))])),
            "lambda_mesh_fit_max_diff_deg": float(np.degrees(np.nanmax(np.abs(
                mesh["lambda"] - cad_mesh["lambda"])))),
            "lambda_mesh_fit_worst_gamma_deg": float(np.degrees(g[np.nanargmax(np.abs(
                mesh["lambda"] - cad_mesh["lambda"]))])),
            "lambda_method_error_deg": float(np.degrees(np.nanmax(np.abs(
                cad_mesh["lambda"] - cad["lambda"])))),
            "theta_max_diff_deg": float(np.degrees(np.nanmax(np.abs(theta - cad["theta"])))),
            "theta_worst_gamma_deg": float(np.degrees(g[np.nanargmax(np.abs(theta
                                                                          - cad["theta"]))])),
            "alpha_max_diff_deg": float(np.degrees(np.nanmax(np.abs(alpha - cad["alpha"])))),
            "theta_facet_max_diff_deg": float(np.degrees(np.nanmax(np.abs(
                mesh["theta"] - cad["theta"])))),
            "l_c_mm": {"milled": getattr(rm, wall).length, "cad": getattr(rc, wall).length}}
    out["angles"] = angles
    out["gamma_compared"] = (f"{len(g)} angles in [{heel_margin_deg:g}°, "
                             f"{360 - heel_margin_deg:g}°]"
                             + (f", {math.degrees(kink_margin):.1f}° from rim corners"
                                if kinks else ""))
    return out


def _near_ridges(res: MilledTip, width: float) -> BoolArray:
    """(ny, nx) bool: grid columns within ``width`` mm (in X and Y) of a
    ridge between two CAD faces (where the CAD normal turns by more than 1°
    from one column to the next)."""
    from scipy.ndimage import binary_dilation

    turn = np.zeros(res.nz.shape, bool)
    cos1 = math.cos(math.radians(1.0))
    n = res.normals
    for axis in (0, 1):
        a = np.take(n, np.arange(n.shape[axis] - 1), axis=axis)
        b = np.take(n, np.arange(1, n.shape[axis]), axis=axis)
        c = np.sum(a * b, axis=-1)
        jump = np.isfinite(c) & (c < cos1)
        sl = [slice(None)] * 2
        sl[axis] = slice(0, -1)
        turn[tuple(sl)] |= jump
    if not turn.any():
        return turn
    kx = int(math.ceil(width / (res.x[1] - res.x[0])))
    ky = int(math.ceil(width / (res.y[1] - res.y[0])))
    wide = binary_dilation(turn, structure=np.ones((1, 2 * kx + 1), bool))
    out: BoolArray = binary_dilation(wide, structure=np.ones((2 * ky + 1, 1), bool))
    return out


def _window(res: MilledTip, gamma: FloatArray, radius: float, stepover: float,
            kinks: FloatArray, ridge: float, periods: float = 4.0) -> FloatArray:
    """Arc lengths (m,) mm of the windows along the rim at cannula angles
    ``gamma`` that span ``periods`` scallop periods P = stepover / |sin β|
    (β between the rim and the passes), at most a quarter of the rim, and
    kept ``ridge`` mm from the rim corners at cannula angles ``kinks``."""
    phi = gamma - res.clocking                      # program-frame angle of the rim point
    sin_b = np.abs(np.cos(phi))                     # rim tangent (−sin φ, cos φ) against X
    L = np.minimum(periods * stepover / np.maximum(sin_b, tol.cam.mill_sin_floor),
                   0.5 * math.pi * radius)
    if len(kinks):
        d = np.min(np.abs(np.angle(np.exp(1j * (gamma[:, None] - np.asarray(kinks)[None])))),
                   axis=1)
        L = np.minimum(L, np.maximum(2.0 * (radius * d - ridge), 2.0 * stepover))
    return L


def _edge_deviation_slope(res: MilledTip, spec: TipSpec, gamma: FloatArray, radius: float,
                          side: float, length: FloatArray) -> FloatArray:
    """d(milled − CAD)/ds along an edge (mm/mm; s the arc length at ``radius``
    towards +γ, just inside the wall: ``side`` −1 outer, +1 inner) at cannula
    angles ``gamma`` (rad), averaged over whole scallops.

    The passes run along program X, ``stepover`` apart in Y, so the scallops
    make the edge's deviation ripple with period P = stepover / |sin β| along
    the rim, β the angle between the rim and the passes (P = ∞ where the rim
    runs along a pass: no ripple there). The slope is a Hann-weighted least
    squares fit over ``length`` (m,) mm (:func:`_window`: 4 P): over four
    whole periods with smooth ends a ripple of amplitude A leaves a slope
    below 0.02 A/P (checked on a sine and on a cusp profile of any phase); a
    plain fit over one period leaves up to 1.8 A/P, and the edge's own local
    slope swings by 2πA/P — at the three-plane tip's heel (A ≈ 3.5 µm
    vertically, P ≈ 0.12 mm at a 2 µm scallop) about ±10° of λ."""
    k = 41
    u = np.linspace(-0.5, 0.5, k)[None, :] * length[:, None]       # (m, k) arc offsets
    w = np.cos(math.pi * np.linspace(-0.5, 0.5, k)) ** 2            # Hann
    ga = gamma[:, None] + u / radius
    rr = radius + side * tol.cam.mill_inside
    xy = np.column_stack([(rr * np.cos(ga)).ravel(), (rr * np.sin(ga)).ravel()])
    dev = (res.heights_at(spec, xy) - cad_height(spec, xy[:, 0], xy[:, 1])).reshape(ga.shape)
    um = np.sum(w * u, 1, keepdims=True) / w.sum()
    dm = np.sum(w * dev, 1, keepdims=True) / w.sum()
    out: FloatArray = np.sum(w * (u - um) * (dev - dm), 1) / np.sum(w * (u - um) ** 2, 1)
    return out


def _fit_normals(res: MilledTip, spec: TipSpec, gamma: FloatArray, radius: float, side: float,
                 length: FloatArray, into: float) -> FloatArray:
    """Unit normals (cannula frame) of the milled surface at the edge points
    (γ rad, radius mm): the exact CAD normal there, tilted by the gradient of
    the deviation milled − CAD fitted as c₀ + c_u u + c_r ρ over a band along
    the rim (arc length u over ``length`` (m,) mm, Hann-weighted: whole
    scallop periods, see :func:`_edge_deviation_slope`) and ``into`` mm into
    the wall (ρ radial, on the wall's side ``side``). Fitting the deviation
    rather than the heights keeps the surface's own curvature out of the fit;
    the scallops ripple with program Y only, so averaging along the rim at
    each depth removes them from both slopes."""
    k = 41
    t = np.linspace(-0.5, 0.5, k)
    w = np.cos(math.pi * t) ** 2
    b = np.linspace(0.02, 1.0, 5)
    u = (t[None, :, None] * length[:, None, None]) * np.ones((1, 1, len(b)))   # (m, k, nb)
    rho = np.broadcast_to(side * b[None, None, :] * into, u.shape)
    ga = gamma[:, None, None] + u / radius
    rr = radius + rho
    xy = np.column_stack([(rr * np.cos(ga)).ravel(), (rr * np.sin(ga)).ravel()])
    dev = (res.heights_at(spec, xy) - cad_height(spec, xy[:, 0], xy[:, 1])).reshape(u.shape)
    W = np.broadcast_to(w[None, :, None], u.shape).reshape(len(gamma), -1)
    X = np.stack([np.ones_like(u), u, rho], -1).reshape(len(gamma), -1, 3)
    y = dev.reshape(len(gamma), -1)
    XtW = X.transpose(0, 2, 1) * W[:, None, :]
    coef = np.linalg.solve(XtW @ X, (XtW @ y[..., None]))[..., 0]      # (m, 3)
    c, s_ = np.cos(gamma), np.sin(gamma)
    gx = coef[:, 1] * -s_ + coef[:, 2] * c
    gy = coef[:, 1] * c + coef[:, 2] * s_
    inward = radius + side * tol.cam.mill_inside
    _, n0 = cad_height(spec, inward * c, inward * s_, normals=True)
    gx = -n0[:, 0] / n0[:, 2] + gx
    gy = -n0[:, 1] / n0[:, 2] + gy
    n = np.stack([-gx, -gy, np.ones_like(gx)], 1)
    out: FloatArray = n / np.linalg.norm(n, axis=1, keepdims=True)
    return out


@styled
def plot_deviation(res: MilledTip, path: str | Path, *, title: str = "",
                   limit_um: float | None = None) -> str | Path:
    """PNG of the signed deviation map (µm, program frame) — written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tipgeo.plot import save_figure

    dev = res.deviation() * 1e3
    lim = limit_um or float(np.nanpercentile(np.abs(dev), 99.5))
    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    im = ax.imshow(dev, origin="lower", cmap="RdBu_r", vmin=-lim, vmax=lim,
                   extent=(res.x[0], res.x[-1], res.y[0], res.y[-1]), interpolation="nearest")
    ax.set_xlabel("program X (mm, along the passes)")
    ax.set_ylabel("program Y (mm)")
    ax.set_title(title or "milled − CAD, normal to the surface")
    fig.colorbar(im, ax=ax, label="deviation (µm, + = material left)")
    try:
        save_figure(fig, path)
    finally:
        plt.close(fig)
    return path


@styled
def plot_toolpath(toolpath: MillToolpath, path: str | Path, *, title: str = "") -> str | Path:
    """PNG of the planned passes (program frame, mm), written atomically:
    the plan view (finishing passes coloured by Z, roughing grey, the wall's
    rims) and the side view X–Z of the finishing passes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    from tipgeo.plot import save_figure

    st = toolpath.setup
    fin = [p.points for p in toolpath.passes if p.kind == "finish"]
    rough = [p.points for p in toolpath.passes if p.kind == "rough"]
    zall = np.concatenate([p[:, 2] for p in fin])
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12.0, 5.4), layout="constrained",
                                 gridspec_kw={"width_ratios": [1.0, 1.1]})
    try:
        if rough:
            ax.add_collection(LineCollection([p[:, :2] for p in rough], colors="0.8",
                                             linewidths=0.6, label="roughing"))
        segs = np.concatenate([np.stack([p[:-1, :2], p[1:, :2]], 1) for p in fin])
        zc = np.concatenate([0.5 * (p[:-1, 2] + p[1:, 2]) for p in fin])
        lc = LineCollection(list(segs), array=zc, cmap="viridis", linewidths=0.9)
        lc.set_clim(zall.min(), zall.max())
        ax.add_collection(lc)
        t = np.linspace(0, 2 * math.pi, 361)
        for r in (st.r_o, st.r_i):
            ax.plot(r * np.cos(t), r * np.sin(t), "k-", lw=0.8)
        lim = st.r_o + toolpath.tool.radius + toolpath.params.lead + 0.1
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_xlabel("program X (mm, along the passes)")
        ax.set_ylabel("program Y (mm)")
        ax.set_title(f"plan: {len(fin)} finishing passes, step-over "
                     f"{st.stepover * 1e3:.0f} µm\n(grey: {len(rough)} roughing passes)",
                     fontsize=10)
        fig.colorbar(lc, ax=ax, label="Z of the tool tip (mm)")
        for p in fin:
            bx.plot(p[:, 0], p[:, 2], lw=0.5, color=plt.cm.coolwarm(
                (p[0, 1] + lim) / (2 * lim)))
        bx.axhline(st.z_top, color="k", ls="--", lw=0.8, label=f"stock top Z{st.z_top:.3f}")
        bx.set_xlabel("program X (mm)")
        bx.set_ylabel("Z of the tool tip (mm)")
        bx.set_title("side view of the finishing passes (colour: program Y)", fontsize=10)
        bx.legend(loc="best", fontsize=8)
        fig.suptitle(title or f"{toolpath.name}: toolpaths, {toolpath.tool.describe()}")
        save_figure(fig, path)
    finally:
        plt.close(fig)
    return path
