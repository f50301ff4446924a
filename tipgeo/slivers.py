"""Sliver removal on a labelled triangle mesh (issue 27 item 4).

Booleans between tessellations whose vertices do not line up leave sliver
triangles: needles (one edge far shorter than the others) and caps (one
angle near 180°). They carry no geometry, but self-intersection checks
(MeshLab, open3d, trimesh) report false positives on them and meshers choke.

Aspect ratio here is the *longest edge over the shortest altitude*,
``L_max² / (2 A)`` (an equilateral triangle: 2/√3 ≈ 1.155; a right isosceles
triangle: 2).

:func:`remove_slivers` improves every triangle above a bound with local
operations, each checked before it is made:

- **edge flip** inside one label, where the two triangles are coplanar
  within the deviation budget;
- **edge split** at a point of the edge (never moves the surface); for a
  cap whose apex cannot collapse onto it, the new point then
  relaxes into its face (onto the exact surface);
- **relaxation** of a vertex inside one label whose triangles lie in one
  plane, to the mean of its neighbours (the surface does not move);
- **edge collapse** of a short edge: a vertex inside one label moves onto a
  neighbour; a vertex on the curve between two labels slides along that
  curve only (so the boundary-of-label curves keep their shape); a vertex
  where three or more labels meet never moves.

Every flip and collapse is refused when it would move the surface, together
with the earlier edits there, by more than ``max_deviation`` (mm) — a small
share of the chordal tolerance —, folds a triangle (its normal
turns by more than 30°), or breaks the 2-manifold (link condition). Labels
are kept triangle by triangle; the result stays watertight.

With the **exact surfaces** of the labels (``exact``: label →
``fn(points) -> (f, ∇f)``, as :func:`tipgeo.build.build_tip` passes the
tube's cylinders and the cutters' implicits), flips, and collapses of a
vertex inside one label, are checked against the exact surface instead of
the budget: every edge midpoint and centroid of the new triangles within
``limit`` (mm) of it (collapses: ``MOVE_SHARE`` × ``limit``; an edit
that fails this check may still pass the budget's). A vertex inside one
label whose star is curved may then move to the mean of its neighbours
*projected onto the exact surface* (Newton steps along ∇f; within
``MOVE_SHARE`` × ``limit``). A vertex on the curve between two labels
whose exact surfaces differ may collapse along that curve onto its
neighbour on it (onto a triple point too), checked against both surfaces
the same way: the new chord of the curve stays within the limit of each
(:func:`_onto_curve` projects a point onto such a curve). An edit whose
faces were already further from the exact surface than the share allows
may keep that distance, never exceed it nor ``limit``. Fold checks compare
every new normal with the old one and with the area-weighted normal of the
star's faces of its label (a sliver's noisy normal cannot vouch for a fold).
The pass keeps the state of its best pass (fewest triangles above the
bound). Then come **trial edits** (:func:`_polish`) on the triangles still
above it, worst first: every collapse and flip of the triangle's edges and a
**refinement** (its longest edge halved, the new vertex relaxed into the
face, flips around it and its neighbours — a needle whose short edge is a
feature gets a vertex nearer that edge) is made, measured on the faces it
changed and undone; the one that leaves the fewest triangles above the
bound there (then the smallest worst) is made again when it beats what was
there. The greedy order misses these: an edit that makes a neighbour worse
for a pass, or a collapse that only helps once another is made. In the
trial edits a face already further from its exact surface than the share
may go up to ``limit`` (not only to where it was).
:func:`remove_slivers_checked` re-runs the passes with the places where
triangles came to cross guarded: edits there (splits too) are checked
against the faces around for crossings; the trial edits run on the best
round's result and are kept when they add no crossing.

Frame and units: whatever the input (tipgeo: cannula frame, mm).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from .arrays import BoolArray, FloatArray, IntArray
from .tolerances import tol

__all__ = ["aspect_ratios", "remove_slivers", "remove_slivers_checked", "snap_float32"]

_FOLD_COS = math.cos(math.radians(30.0))

#: Share of ``limit`` within which collapses and relocations checked
#: against the exact surface may leave it (flips may use all of it).
MOVE_SHARE = 0.5

#: Smallest sin² of the angle between two exact surfaces for which a point is
#: projected onto their intersection curve (about 1.8°).
CURVE_MIN_SIN2 = 1.0e-3

#: Share of ``limit`` within which a point projected onto the curve between
#: two exact surfaces must land on both.
CURVE_SETTLE = 0.01

#: Share of ``limit`` within which a new vertex settled onto the curve
#: between two exact surfaces (:meth:`_Mesh.settle`) must land on both: to
#: rounding (Gauss–Newton converges quadratically; a step or two more than
#: ``CURVE_SETTLE`` takes).
SETTLE_CURVE = 1.0e-6

#: Most Gauss–Newton steps onto the curve between two exact surfaces.
CURVE_STEPS_MAX = 6

#: Rounds of :func:`remove_slivers_checked` that guard the places where
#: triangles crossed (edits there checked for crossings) before it freezes
#: them.
GUARD_ROUNDS = 3

#: Passes without fewer triangles above the bound after which the pass stops.
STALL_PASSES = 6

#: Rounds of trial edits (each kept only where it helps) after the passes.
POLISH_ROUNDS = 4

#: A point or a vector (mm).
Vec = tuple[float, float, float]

#: ``fn(points (k, 3) mm) -> (f (k,), grad f (k, 3))``: an exact surface f = 0
#: (f in mm to first order; cannula frame).
Implicit = Callable[[FloatArray], tuple[FloatArray, FloatArray]]


def aspect_ratios(vertices: FloatArray, faces: IntArray) -> FloatArray:
    """(m,) longest edge / shortest altitude of every triangle
    (``L_max² / (2·area)``; ``inf`` for a zero-area triangle)."""
    t = np.asarray(vertices, float)[np.asarray(faces, np.int64)]
    e2 = np.stack([((t[:, 1] - t[:, 0]) ** 2).sum(1), ((t[:, 2] - t[:, 1]) ** 2).sum(1),
                   ((t[:, 0] - t[:, 2]) ** 2).sum(1)], 1)
    a2 = np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)  # 2·area
    with np.errstate(divide="ignore", invalid="ignore"):
        out: FloatArray = np.where(a2 > 0, e2.max(1) / np.where(a2 > 0, a2, 1.0), np.inf)
    return out


def _ar(p0: Vec, p1: Vec, p2: Vec) -> float:
    e = max(_d2(p0, p1), _d2(p1, p2), _d2(p2, p0))
    a2 = _norm(_cross(_sub(p1, p0), _sub(p2, p0)))
    return e / a2 if a2 > 0 else math.inf


def _sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _norm(a: Vec) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


def _d2(a: Vec, b: Vec) -> float:
    return (a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2


def _mid(a: Vec, b: Vec) -> Vec:
    return (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2]))


def _mid3(a: Vec, b: Vec, c: Vec) -> Vec:
    return ((a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0, (a[2] + b[2] + c[2]) / 3.0)


def _unit_normal(p0: Vec, p1: Vec, p2: Vec) -> Vec | None:
    n = _cross(_sub(p1, p0), _sub(p2, p0))
    s = _norm(n)
    return None if s == 0 else (n[0] / s, n[1] / s, n[2] / s)


def _point_triangle(p: Vec, a: Vec, b: Vec, c: Vec) -> float:
    """Distance from p to the triangle abc (Ericson, Real-Time Collision
    Detection §5.1.5)."""
    ab, ac, ap = _sub(b, a), _sub(c, a), _sub(p, a)
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    if d1 <= 0 and d2 <= 0:
        return math.sqrt(_d2(p, a))
    bp = _sub(p, b)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    if d3 >= 0 and d4 <= d3:
        return math.sqrt(_d2(p, b))
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        v = d1 / (d1 - d3)
        q = (a[0] + v * ab[0], a[1] + v * ab[1], a[2] + v * ab[2])
        return math.sqrt(_d2(p, q))
    cp = _sub(p, c)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    if d6 >= 0 and d5 <= d6:
        return math.sqrt(_d2(p, c))
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        w = d2 / (d2 - d6)
        q = (a[0] + w * ac[0], a[1] + w * ac[1], a[2] + w * ac[2])
        return math.sqrt(_d2(p, q))
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        q = (b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2]))
        return math.sqrt(_d2(p, q))
    denom = 1.0 / (va + vb + vc)
    v, w = vb * denom, vc * denom
    q = (a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w,
         a[2] + ab[2] * v + ac[2] * w)
    return math.sqrt(_d2(p, q))


def _corners(tri: Sequence[int], p: Sequence[Vec]) -> tuple[Vec, Vec, Vec]:
    """The three corner points of the triangle ``tri`` (indices into ``p``)."""
    return p[tri[0]], p[tri[1]], p[tri[2]]


def _onto_curve(q: Vec, fa: Implicit, fb: Implicit, limit: float) -> Vec | None:
    """q moved onto the curve fa = fb = 0 (Gauss–Newton on the two
    implicits: the least step that zeroes both to first order); None when
    the surfaces meet at too small an angle to locate the curve or the
    steps do not bring both within ``CURVE_SETTLE`` × ``limit`` (mm)."""
    x = np.asarray([q], np.float64)
    for _ in range(CURVE_STEPS_MAX):
        f1, g1 = fa(x)
        f2, g2 = fb(x)
        r1, r2 = float(f1[0]), float(f2[0])
        if max(abs(r1), abs(r2)) <= CURVE_SETTLE * limit:
            return float(x[0, 0]), float(x[0, 1]), float(x[0, 2])
        a, b = g1[0], g2[0]
        m00, m01, m11 = float(a @ a), float(a @ b), float(b @ b)
        det = m00 * m11 - m01 * m01
        if not det > CURVE_MIN_SIN2 * m00 * m11:
            return None
        c1 = (m11 * r1 - m01 * r2) / det
        c2 = (m00 * r2 - m01 * r1) / det
        x = x - (c1 * a + c2 * b)[None, :]
    return None


@dataclasses.dataclass
class _Snap:
    """What :meth:`_Mesh._restore` puts back: list sizes, vertex → point,
    face → (corners, label, alive, deviation)."""

    n_faces: int
    added: int
    verts: dict[int, Vec]
    faces: dict[int, tuple[list[int], int, bool, float]]


class _Mesh:
    """Mutable triangle soup with vertex→faces incidence."""

    def __init__(self, vertices: FloatArray, faces: IntArray, labels: IntArray,
                 frozen: Iterable[int] = (), exact: Mapping[int, Implicit] | None = None,
                 limit: float = 0.0) -> None:
        self.frozen = set(int(x) for x in frozen)  # vertices no edit may touch
        self.exact: Mapping[int, Implicit] = exact or {}  # label -> exact surface
        self.limit = limit  # largest |f| of an exact surface over an edited face (mm)
        self.relaxed = False  # faces beyond the share may go up to the limit (trial edits)
        self.p: list[Vec] = [(float(v[0]), float(v[1]), float(v[2])) for v in vertices]
        self.f = [list(map(int, t)) for t in faces]
        self.lab = [int(x) for x in labels]
        self.alive = [True] * len(self.f)
        self.dev = [0.0] * len(self.f)  # how far edits have moved each face so far (mm)
        self.added = 0  # vertices added by splits
        self.zone: dict[int, int] = {}  # guarded vertex -> its zone (edits there: crossing-checked)
        self.zones: list[set[int]] = []
        self.reach: list[float] = []  # per zone: twice its longest edge (mm)
        self.dirty: set[int] = set()  # faces changed since the last pass
        self.vf: list[set[int]] = [set() for _ in self.p]
        for k, (a, b, c) in enumerate(self.f):
            self.vf[a].add(k)
            self.vf[b].add(k)
            self.vf[c].add(k)

    # -- queries ---------------------------------------------------------------
    def ar(self, k: int) -> float:
        return _ar(*_corners(self.f[k], self.p))

    def normal(self, k: int) -> Vec | None:
        return _unit_normal(*_corners(self.f[k], self.p))

    def edge_faces(self, a: int, b: int) -> list[int]:
        return list(self.vf[a] & self.vf[b])

    def labels_at(self, v: int) -> set[int]:
        return {self.lab[k] for k in self.vf[v]}

    def set_guard(self, zones: Iterable[Iterable[int]]) -> None:
        """Guarded zones (vertex sets): an edit with a new triangle touching
        one is made only when none of its new triangles crosses a triangle
        around the zone (:meth:`crossing_free`)."""
        for z in zones:
            zs = {int(x) for x in z}
            for x in zs:
                self.zone.setdefault(x, len(self.zones))
            self.zones.append(zs)
            # the zone's longest edge: how far a face's corner may lie from
            # a point of it (edits there only shorten the worst edges much)
            reach = 0.0
            for x in zs:
                for y in self.neighbours(x):
                    reach = max(reach, _d2(self.p[x], self.p[y]))
            self.reach.append(2.0 * math.sqrt(reach))

    def crossing_free(self, new: Sequence[Sequence[int]], drop: Iterable[int]) -> bool:
        """True unless a triangle of ``new`` (vertex triples; the faces
        ``drop`` are the ones they replace) touches a guarded zone and
        crosses (:func:`tipgeo.meshcheck.self_intersections`) or is taken
        for a crossing by the tolerant test
        (:func:`tipgeo.meshcheck.tolerant_intersections`) with a face of that
        zone or around the new triangles."""
        hit = {self.zone[x] for t in new for x in t if x in self.zone}
        if not hit:
            return True
        from .meshcheck import self_intersections, tolerant_intersections

        corners = np.asarray([self.p[x] for t in new for x in t], np.float64)
        lo, hi = corners.min(0) - self.limit, corners.max(0) + self.limit
        near = self._near_faces(new, set(drop), hit, lo, hi)
        old = [self.f[k] for k in near]
        tris = np.asarray(old + [list(t) for t in new], np.int64)
        used, inv = np.unique(tris, return_inverse=True)
        pts = np.asarray([self.p[int(x)] for x in used], np.float64)
        faces = inv.reshape(-1, 3)
        for pairs in (self_intersections(pts, faces), tolerant_intersections(pts, faces)):
            if len(pairs) and bool((pairs >= len(old)).any()):
                return False
        return True

    def _near_faces(self, new: Sequence[Sequence[int]], gone: set[int], hit: set[int],
                    lo: FloatArray, hi: FloatArray) -> list[int]:
        """The live faces (but ``gone``) at the zones ``hit`` or around the
        triangles ``new`` whose box meets the box ``lo``–``hi`` (mm)."""
        near: set[int] = set()
        for z in hit:  # faces at the zone's vertices within its reach of the box
            zv = list(self.zones[z])
            zp = np.asarray([self.p[x] for x in zv], np.float64)
            r = self.reach[z]
            for i in np.flatnonzero(((zp >= lo - r) & (zp <= hi + r)).all(1)):
                near |= self.vf[zv[i]]
        for t in new:
            for x in t:
                for y in self.neighbours(x):
                    near |= self.vf[y]
        # of those, the faces whose box meets the box (a long face may pass
        # by with its corners far away)
        cand = [k for k in near - gone if self.alive[k]]
        if not cand:
            return []
        box = np.asarray([_corners(self.f[k], self.p) for k in cand], np.float64)
        meet = ((box.min(1) <= hi) & (box.max(1) >= lo)).all(1)
        return [cand[i] for i in np.flatnonzero(meet)]

    def label_normals(self, faces: Iterable[int]) -> dict[int, Vec]:
        """label -> unit area-weighted normal of the given faces of that
        label (a sliver's noisy normal weighs nothing); labels whose faces
        have no area are left out."""
        acc: dict[int, Vec] = {}
        for k in faces:
            a, b, c = _corners(self.f[k], self.p)
            n = _cross(_sub(b, a), _sub(c, a))
            m = acc.get(self.lab[k], (0.0, 0.0, 0.0))
            acc[self.lab[k]] = (m[0] + n[0], m[1] + n[1], m[2] + n[2])
        out: dict[int, Vec] = {}
        for lab, n in acc.items():
            size = _norm(n)
            if size > 0:
                out[lab] = (n[0] / size, n[1] / size, n[2] / size)
        return out

    def neighbours(self, v: int) -> set[int]:
        out: set[int] = set()
        for k in self.vf[v]:
            out.update(self.f[k])
        out.discard(v)
        return out

    @staticmethod
    def opposite(tri: Sequence[int], a: int, b: int) -> int:
        for x in tri:
            if x != a and x != b:
                return x
        raise ValueError("degenerate triangle")

    def exact_dev(self, tris: Iterable[tuple[Sequence[int], int]]) -> float | None:
        """None when a label of the triangles ``(corners, label)`` has no
        exact surface; else the largest |f| (mm) of its label's exact
        surface over their edge midpoints and centroids."""
        by: dict[int, list[Vec]] = {}
        for t, lab in tris:
            if lab not in self.exact:
                return None
            a, b, c = _corners(t, self.p)
            by.setdefault(lab, []).extend((_mid(a, b), _mid(b, c), _mid(c, a), _mid3(a, b, c)))
        worst = 0.0
        for lab, pts in by.items():
            f = self.exact[lab](np.asarray(pts, np.float64))[0]
            worst = max(worst, float(np.abs(f).max()))
        return worst

    def exact_ok(self, tris: Iterable[tuple[Sequence[int], int]],
                 share: float = 1.0, before: float = 0.0) -> bool | None:
        """None when a label of the triangles ``(corners, label)`` has no
        exact surface; else whether every edge midpoint and centroid lies
        within ``share`` × ``limit`` (mm) of its label's exact surface — or,
        where the faces the edit replaces were further (``before``, mm),
        no further than they were, and within ``limit``."""
        dev = self.exact_dev(tris)
        if dev is None:
            return None
        if self.relaxed and before > share * self.limit:
            return dev <= self.limit
        return dev <= min(max(share * self.limit, before), self.limit)

    def curve_fns(self, u: int) -> tuple[Implicit, Implicit] | None:
        """The two exact surfaces whose intersection curve u lies on (u on
        exactly two labels, each with its own exact surface); else None."""
        labs = self.labels_at(u)
        if len(labs) != 2:
            return None
        fa, fb = (self.exact.get(lab) for lab in labs)
        if fa is None or fb is None or fa is fb:
            return None  # faces of one implicit: their crease is not located
        return fa, fb

    def project(self, u: int, q: Vec) -> Vec | None:
        """q moved onto the exact surface of u's one label (Newton steps
        along the gradient), or for u on the curve between two labels onto
        that curve (:func:`_onto_curve`); None when u's labels have no exact
        surfaces or the steps do not settle."""
        labs = self.labels_at(u)
        if len(labs) == 2:
            fns = self.curve_fns(u)
            return None if fns is None else _onto_curve(q, *fns, self.limit)
        if len(labs) != 1:
            return None
        fn = self.exact.get(next(iter(labs)))
        if fn is None:
            return None
        x = np.asarray([q], np.float64)
        for _ in range(4):
            f, g = fn(x)
            gg = float((g[0] ** 2).sum())
            if not gg > 0.0:
                return None
            x = x - (float(f[0]) / gg) * g
        return float(x[0, 0]), float(x[0, 1]), float(x[0, 2])

    def _set(self, k: int, tri: Sequence[int]) -> None:
        self.dirty.add(k)
        for x in self.f[k]:
            self.vf[x].discard(k)
        self.f[k] = list(tri)
        for x in tri:
            self.vf[x].add(k)

    def _add(self, tri: Sequence[int], label: int, dev: float = 0.0) -> int:
        k = len(self.f)
        self.dirty.add(k)
        self.f.append(list(tri))
        self.lab.append(label)
        self.alive.append(True)
        self.dev.append(dev)
        for x in tri:
            self.vf[x].add(k)
        return k

    def _kill(self, k: int) -> None:
        for x in self.f[k]:
            self.vf[x].discard(k)
        self.alive[k] = False

    @staticmethod
    def _rot(tri: list[int], a: int) -> list[int]:
        """tri rotated so that it starts at a."""
        i = tri.index(a)
        return tri[i:] + tri[:i]

    def _flip_quad(self, a: int, b: int) -> tuple[int, int, int, int] | None:
        """The two faces (f, g) on the edge ab as f = (a, b, c), g = (b, a, d),
        with c and d, when the edge may flip (one label, nothing frozen, the
        new edge cd not there yet); else None."""
        fs = self.edge_faces(a, b)
        if len(fs) != 2:
            return None
        f, g = fs
        if self.lab[f] != self.lab[g]:
            return None
        tf = self._rot(self.f[f], a)
        if tf[1] != b:  # make f = (a, b, c), g = (b, a, d)
            f, g = g, f
            tf = self._rot(self.f[f], a)
            if tf[1] != b:
                return None
        c = tf[2]
        d = self.opposite(self.f[g], a, b)
        if self.frozen and self.frozen & {a, b, c, d}:
            return None
        if c == d or g in self.vf[c] or (self.vf[c] & self.vf[d]):
            return None
        return f, g, c, d

    def try_flip(self, a: int, b: int, max_dev: float) -> bool:
        quad = self._flip_quad(a, b)
        if quad is None:
            return False
        f, g, c, d = quad
        pa, pb, pc, pd = self.p[a], self.p[b], self.p[c], self.p[d]
        n1, n2 = _unit_normal(pa, pb, pc), _unit_normal(pb, pa, pd)
        m1, m2 = _unit_normal(pa, pd, pc), _unit_normal(pd, pb, pc)
        if n1 is None or n2 is None or m1 is None or m2 is None:
            return False
        ref = self.label_normals(self.vf[a] | self.vf[b] | self.vf[c] | self.vf[d]).get(self.lab[f])
        if ref is None:
            return False
        for m in (m1, m2):  # against the old faces and the neighbourhood's normal
            if _dot(m, n1) < _FOLD_COS or _dot(m, n2) < _FOLD_COS or _dot(m, ref) < _FOLD_COS:
                return False
        if max(_ar(pa, pd, pc), _ar(pd, pb, pc)) >= max(_ar(pa, pb, pc), _ar(pb, pa, pd)):
            return False
        if not self.crossing_free([(a, d, c), (d, b, c)], (f, g)):
            return False
        ok = self.exact_ok([((a, d, c), self.lab[f]), ((d, b, c), self.lab[g])])
        if ok:  # measured against the exact surface
            self._set(f, (a, d, c))
            self._set(g, (d, b, c))
            return True
        dev = (max(self.dev[f], self.dev[g])
               + max(abs(_dot(_sub(pd, pa), n1)), abs(_dot(_sub(pc, pa), n2))))
        if dev > max_dev:
            return False
        self._set(f, (a, d, c))
        self._set(g, (d, b, c))
        self.dev[f] = self.dev[g] = dev
        return True

    def split(self, a: int, b: int, point: Vec) -> int | None:
        """Insert ``point`` (on the edge ab) as a new vertex; returns its
        index. In a guarded zone, None (and nothing done) when a part
        crosses a face near it: the parts cover what the faces covered, but
        a part no longer sharing a vertex with a face that touched its
        parent at that vertex is tested as a crossing."""
        fs = self.edge_faces(a, b)
        before = [list(self.f[k]) for k in fs]
        v = len(self.p)
        self.added += 1
        self.p.append(point)
        self.vf.append(set())
        if a in self.zone or b in self.zone:
            z = self.zone.get(a, self.zone.get(b, 0))
            self.zone[v] = z
            self.zones[z].add(v)
        made: list[int] = []
        for k in fs:
            t = self.f[k]
            i = t.index(a)
            j = t.index(b)
            t1, t2 = list(t), list(t)
            t1[j] = v  # (.., a, v, ..) keeps orientation
            t2[i] = v
            self._set(k, t1)
            made.append(self._add(t2, self.lab[k], self.dev[k]))
        parts = list(fs) + made
        if not self.crossing_free([self.f[k] for k in parts], parts):
            for k in made:
                self._kill(k)
            for k, t in zip(fs, before):
                self._set(k, t)
            return None
        return v

    def _collapse_allowed(self, u: int, v: int) -> list[int] | None:
        """The two faces on the edge uv when u may move onto v (nothing
        frozen, u on at most two labels and, on two, sliding along their
        curve, the link condition); else None."""
        if u in self.frozen or v in self.frozen:
            return None
        fs = self.edge_faces(u, v)
        if len(fs) != 2:
            return None
        lu = self.labels_at(u)
        if len(lu) >= 3:
            return None
        if len(lu) == 2 and self.lab[fs[0]] == self.lab[fs[1]]:
            return None  # u on a label curve may only slide along it
        opp = {self.opposite(self.f[k], u, v) for k in fs}
        if self.neighbours(u) & self.neighbours(v) != opp:
            return None  # link condition
        return fs

    def _collapse_faces(self, u: int, v: int, fs: list[int]) -> list[tuple[int, list[int]]] | None:
        """The faces around u (but the two on uv) re-made with v for u, when
        none folds and each beats the star's worst aspect ratio; else None."""
        worst_old = max(self.ar(k) for k in self.vf[u])
        ref = self.label_normals(self.vf[u])
        new = []
        for k in self.vf[u]:
            if k in fs:
                continue
            t = [v if x == u else x for x in self.f[k]]
            q = _corners(t, self.p)
            n_new = _unit_normal(*q)
            n_old = self.normal(k)
            if n_new is None or n_old is None or _dot(n_new, n_old) < _FOLD_COS:
                return None
            r = ref.get(self.lab[k])
            if r is None or _dot(n_new, r) < _FOLD_COS:
                return None  # against the star's own (area-weighted) normal too
            if _ar(*q) >= worst_old:
                return None
            new.append((k, t))
        return new

    def _collapse_moves(self, u: int, v: int, fs: list[int],
                        new: list[tuple[int, list[int]]]) -> float:
        """How far moving u onto v moves the surface (mm; inf when a label
        of u keeps no face): the distance of u from the new surface of each of
        its labels, and of the new triangles' edge midpoints and centroids
        from the old star."""
        pu = self.p[u]
        moved_by = 0.0
        for lab in self.labels_at(u):
            cand = [t for k, t in new if self.lab[k] == lab]
            cand += [self.f[k] for k in self.vf[v] if k not in fs and self.lab[k] == lab]
            if not cand:
                return math.inf
            moved_by = max(moved_by, min(_point_triangle(pu, *_corners(t, self.p))
                                         for t in cand))
        star = [_corners(self.f[k], self.p) for k in self.vf[u]]
        for _, t in new:
            a, b, c = _corners(t, self.p)
            for q in (_mid(a, b), _mid(b, c), _mid(c, a), _mid3(a, b, c)):
                moved_by = max(moved_by, min(_point_triangle(q, *s) for s in star))
        return moved_by

    def try_collapse(self, u: int, v: int, max_dev: float) -> bool:
        """Move vertex u onto v and remove it, where that is allowed, folds
        nothing, improves the star and keeps the deviation (added to how far
        earlier edits moved these faces) within ``max_dev`` (mm)."""
        fs = self._collapse_allowed(u, v)
        if fs is None:
            return False
        new = self._collapse_faces(u, v, fs)
        if new is None or not self.crossing_free([t for _, t in new], self.vf[u]):
            return False
        # a vertex inside one label: checked against the exact surface (on a
        # curve between labels: the budget, so the curves keep their place)
        # (moves within half the limit: the volume and areas stay put)
        ok = None
        if len(self.labels_at(u)) == 1 or self.curve_fns(u) is not None:
            before = self.exact_dev((self.f[k], self.lab[k]) for k in self.vf[u])
            ok = self.exact_ok(((t, self.lab[k]) for k, t in new), MOVE_SHARE, before or 0.0)
        if ok:
            for k in fs:
                self._kill(k)
            for k, t in new:
                self._set(k, t)
            return True
        dev = max(self.dev[k] for k in self.vf[u]) + self._collapse_moves(u, v, fs, new)
        if dev > max_dev:
            return False
        for k in fs:
            self._kill(k)
        for k, t in new:
            self._set(k, t)
            self.dev[k] = dev
        return True

    # -- the pass --------------------------------------------------------------
    def fix(self, k: int, max_dev: float) -> bool:
        """One attempt to improve triangle k; True when the mesh changed."""
        t = self.f[k]
        if self.frozen and self.frozen.intersection(t):
            return False
        pts = _corners(t, self.p)
        el = sorted((_d2(pts[i], pts[(i + 1) % 3]), t[i], t[(i + 1) % 3]) for i in range(3))
        (_, sa, sb), (_, la, lb) = el[0], el[2]
        if self.try_flip(la, lb, max_dev):
            return True
        if self.try_collapse(sa, sb, max_dev) or self.try_collapse(sb, sa, max_dev):
            return True
        if any(self.try_relax(x) for x in t):
            return True
        # a cap: split the long edge at the foot of the opposite vertex, then
        # move that vertex onto the foot (or flip the new edges)
        c = self.opposite(t, la, lb)
        pa, pb, pc = self.p[la], self.p[lb], self.p[c]
        ab = _sub(pb, pa)
        s = _dot(_sub(pc, pa), ab) / _dot(ab, ab)
        if not 0.02 < s < 0.98:
            # a needle that cannot collapse (its short edge is a feature):
            # flip its middle edge, else halve its long edge and flip around
            mid = el[1]
            if self.try_flip(mid[1], mid[2], max_dev):
                return True
            s = 0.5
        foot = (pa[0] + s * ab[0], pa[1] + s * ab[1], pa[2] + s * ab[2])
        w = self.split(la, lb, foot)
        if w is None:
            return False
        if self.try_collapse(c, w, max_dev):
            return True
        # c cannot move onto w (a corner, a curve the chord would leave): w, inside
        # one face, moves off the long edge towards its other neighbours
        self.try_relax(w)
        self.flip_around(w, max_dev)
        return True

    def _flat_star(self, u: int) -> bool:
        """Every neighbour of u lies in the plane of u's first face (within
        ``tol.sliver_flat`` of the star's size)."""
        n0 = self.normal(next(iter(self.vf[u])))
        if n0 is None:
            return False
        pu = self.p[u]
        nb = self.neighbours(u)
        scale = max(math.sqrt(_d2(pu, self.p[x])) for x in nb)
        return all(abs(_dot(_sub(self.p[x], pu), n0)) <= tol.sliver_flat * scale for x in nb)

    def try_relax(self, u: int) -> bool:
        """Move u, inside one label and a flat star, to the mean of its
        neighbours (in that plane: the surface does not move) — with a curved
        star, that mean projected onto the exact surface — where that folds
        nothing and improves the star's worst triangle."""
        if u in self.frozen:
            return False
        if len(self.labels_at(u)) != 1:
            return False
        nb = self.neighbours(u)
        q: Vec = (sum(self.p[x][0] for x in nb) / len(nb),
                  sum(self.p[x][1] for x in nb) / len(nb),
                  sum(self.p[x][2] for x in nb) / len(nb))
        exact = not self._flat_star(u)
        if exact:  # a curved star: onto the exact surface, checked against it
            on = self.project(u, q)
            if on is None:
                return False
            q = on
        return self._try_move(u, q, exact)

    def _try_move(self, u: int, q: Vec, exact: bool) -> bool:
        """Move u to q when no face of its star folds (against its old normal
        and its label's area-weighted star normal), the star's worst aspect
        ratio drops and, with ``exact``, the star's edge midpoints and
        centroids stay within ``MOVE_SHARE`` × ``limit`` of the exact
        surfaces; else leave it."""
        star = list(self.vf[u])
        pu = self.p[u]
        old = [self.normal(k) for k in star]
        ref = self.label_normals(star)
        worst = max(self.ar(k) for k in star)
        before = self.exact_dev((self.f[k], self.lab[k]) for k in star) if exact else None
        self.p[u] = q
        if all(self._unfolded(k, nn) and self._unfolded(k, ref.get(self.lab[k]))
               for k, nn in zip(star, old)) and \
                max(self.ar(k) for k in star) < worst and \
                (not exact or self.exact_ok(((self.f[k], self.lab[k]) for k in star),
                                            MOVE_SHARE, before or 0.0)) and \
                self.crossing_free([self.f[k] for k in star], star):
            self.dirty.update(star)
            return True
        self.p[u] = pu
        return False

    def _unfolded(self, k: int, before: Vec | None) -> bool:
        """Face k's normal is within the fold angle of ``before``."""
        now = self.normal(k)
        return before is not None and now is not None and _dot(now, before) > _FOLD_COS

    # -- trial edits ---------------------------------------------------------------
    def _snapshot(self, tri: Sequence[int], rings: int) -> _Snap:
        """The state an edit of triangle ``tri`` may touch: the vertices
        within ``rings`` rings of its corners, their faces, and the list
        sizes."""
        ring = set(tri)
        for _ in range(rings):
            ring |= {y for x in ring for y in self.neighbours(x)}
        faces = {k for x in ring for k in self.vf[x]}
        return _Snap(len(self.f), self.added,
                     {x: self.p[x] for x in ring},
                     {k: (list(self.f[k]), self.lab[k], self.alive[k], self.dev[k])
                      for k in faces})

    def _restore(self, snap: _Snap) -> None:
        """Undo everything since ``snap`` (vertices a split added stay,
        unused): the faces it holds and those added since get their old
        corners back, and the vertex → faces sets follow."""
        for k in list(snap.faces) + list(range(snap.n_faces, len(self.f))):
            for x in self.f[k]:
                self.vf[x].discard(k)
        for k in range(snap.n_faces, len(self.f)):
            self.alive[k] = False
        for k, (tri, lab, alive, dev) in snap.faces.items():
            self.f[k], self.lab[k], self.alive[k], self.dev[k] = list(tri), lab, alive, dev
            if alive:
                for x in tri:
                    self.vf[x].add(k)
        for x, q in snap.verts.items():
            self.p[x] = q
        self.added = snap.added

    def _gain(self, snap: _Snap, bound: float) -> tuple[int, float]:
        """How much better the faces changed since ``snap`` (``dirty``) are
        than the ones they replace: (fewer triangles above ``bound``, lower
        worst aspect ratio); better when greater."""
        gone = {k for k, old in snap.faces.items() if old[2] and not self.alive[k]}
        before = [self._snap_ar(snap, k) for k in self.dirty | gone
                  if k < snap.n_faces and k in snap.faces and snap.faces[k][2]]
        after = [self.ar(k) for k in self.dirty if self.alive[k]]
        nb, na = sum(a > bound for a in before), sum(a > bound for a in after)
        return nb - na, max(before, default=0.0) - max(after, default=0.0)

    def _snap_ar(self, snap: _Snap, k: int) -> float:
        tri = snap.faces[k][0]
        pts = [snap.verts.get(x, self.p[x]) for x in tri]
        return _ar(pts[0], pts[1], pts[2])

    def settle(self, w: int) -> bool:
        """Move w onto the exact surface of its one label, or onto the curve
        where its two labels' exact surfaces meet (:meth:`project`), when no
        face of its star folds, every edge midpoint and centroid of the star
        stays within ``limit`` (mm) of the exact surfaces and nothing crosses;
        True when moved."""
        if w in self.frozen:
            return False
        fns = self.curve_fns(w)
        q = (self.project(w, self.p[w]) if fns is None
             else _onto_curve(self.p[w], *fns, SETTLE_CURVE * self.limit))
        if q is None:
            return False
        star = list(self.vf[w])
        pw = self.p[w]
        old = [self.normal(k) for k in star]
        ref = self.label_normals(star)
        self.p[w] = q
        if all(self._unfolded(k, nn) and self._unfolded(k, ref.get(self.lab[k]))
               for k, nn in zip(star, old)) and \
                self.exact_ok((self.f[k], self.lab[k]) for k in star) and \
                self.crossing_free([self.f[k] for k in star], star):
            self.dirty.update(star)
            return True
        self.p[w] = pw
        return False

    def refine(self, tri: Sequence[int], max_dev: float) -> bool:
        """Split the longest edge of ``tri`` at its middle, move the new
        vertex onto the exact surface, or onto the exact curve when the edge
        lies where two faces meet (:meth:`settle`), then relax it and flip
        around it and its neighbours, twice: a needle whose short edge is a
        feature gets a vertex nearer its base. True when the split was
        made."""
        pts = _corners(tri, self.p)
        _, a, b = max((_d2(pts[i], pts[(i + 1) % 3]), tri[i], tri[(i + 1) % 3])
                      for i in range(3))
        w = self.split(a, b, _mid(self.p[a], self.p[b]))
        if w is None:
            return False
        self.settle(w)
        for _ in range(2):
            self.try_relax(w)
            for x in [w, *sorted(self.neighbours(w))]:
                for kk in sorted(self.vf[x]):  # sorted: the same edits when made again
                    if self.alive[kk] and x in self.f[kk]:
                        tt = self._rot(self.f[kk], x)
                        self.try_flip(tt[1], tt[2], max_dev)
        return True

    def polish(self, k: int, bound: float, max_dev: float) -> bool:
        """Try every collapse and flip of triangle k's edges and
        :meth:`refine`; make the one that leaves the fewest triangles above
        ``bound`` where it changed the mesh (then the smallest worst), when
        that is fewer than before (or as many with a smaller worst); True
        when one was made."""
        t = list(self.f[k])
        if self.frozen and self.frozen.intersection(t):
            return False
        edits: list[Callable[[], bool]] = []
        for i in range(3):
            a, b = t[i], t[(i + 1) % 3]
            edits += [functools.partial(self.try_collapse, a, b, max_dev),
                      functools.partial(self.try_collapse, b, a, max_dev),
                      functools.partial(self.try_flip, a, b, max_dev)]
        edits.append(functools.partial(self.refine, t, max_dev))
        best, gain = None, (0, 0.0)
        for n, edit in enumerate(edits):  # each tried and undone; the best made again
            snap = self._snapshot(t, 3)
            self.dirty = set()
            if edit():
                g = self._gain(snap, bound)
                if g > gain:
                    best, gain = n, g
            self._restore(snap)
        if best is None:
            return False
        snap = self._snapshot(t, 3)
        self.dirty = set()
        if edits[best]() and self._gain(snap, bound) > (0, 0.0):
            return True
        self._restore(snap)  # made again, it did not do what it did on trial
        return False

    def flip_around(self, w: int, max_dev: float) -> None:
        """Flip the edges opposite w where that improves their triangles."""
        for kk in list(self.vf[w]):
            if self.alive[kk] and w in self.f[kk]:
                tt = self._rot(self.f[kk], w)
                self.try_flip(tt[1], tt[2], max_dev)


def remove_slivers(vertices: FloatArray, faces: IntArray, labels: IntArray, *,
                   bound: float, max_deviation: float, max_passes: int = 40,
                   frozen: BoolArray | None = None,
                   exact: Mapping[int, Implicit] | None = None, limit: float = 0.0,
                   guard: Sequence[IntArray] = (), polish: bool = True,
                   ) -> tuple[FloatArray, IntArray, IntArray]:
    """Improve the triangles whose aspect ratio exceeds ``bound``.

    Parameters
    ----------
    vertices : (n, 3) float, faces : (m, 3) int, labels : (m,) int
        A closed, oriented, labelled triangle mesh (mm).
    bound : float
        Target largest aspect ratio (longest edge / shortest altitude).
    max_deviation : float
        Largest distance (mm) by which all flips and collapses together may
        move any part of the surface (tracked per triangle, summed over the
        edits that made it); splits never move it.
    max_passes : int
        Passes over the triangles still above the bound.
    frozen : (n,) bool, optional
        Vertices no edit may move, remove or re-connect (the triangles
        around them are left as they are).
    exact : {label: fn}, optional
        The exact surface of each label that has one (``fn(points) ->
        (f, grad f)``, f in mm to first order). Edits of triangles whose
        labels all have one are checked against them instead of the
        deviation budget: every edge midpoint and centroid of the new
        triangles within ``limit`` (mm) of the exact surface; and a vertex
        inside one such label with a curved star may move to the mean of its
        neighbours projected onto the exact surface.
    limit : float
        See ``exact`` (mm).
    guard : sequence of (k,) int arrays
        Zones of vertices (each where an earlier pass made triangles cross):
        a flip, collapse or move whose new triangles touch a zone is made
        only when none of them crosses a face of that zone or around it
        (exact crossings and the tolerant test's pairs).

    polish : bool
        After the passes, try every collapse and flip of each triangle
        still above the bound and keep those that leave fewer (or a smaller
        worst) where they changed the mesh (:func:`_polish`).

    Returns
    -------
    vertices, faces, labels
        The improved mesh (unused vertices dropped). Triangles the local
        operations cannot improve within the budget stay as they were.
    """
    m = _passes(vertices, faces, labels, bound=bound, max_deviation=max_deviation,
                max_passes=max_passes, frozen=frozen, exact=exact, limit=limit, guard=guard)
    if polish:
        _polish(m, bound, max_deviation)
    return _arrays(m)


def _passes(vertices: FloatArray, faces: IntArray, labels: IntArray, *,
            bound: float, max_deviation: float, max_passes: int,
            frozen: BoolArray | None, exact: Mapping[int, Implicit] | None, limit: float,
            guard: Sequence[IntArray]) -> _Mesh:
    """The greedy passes of :func:`remove_slivers`; the mesh in its best
    state (fewest triangles above ``bound``)."""
    m = _Mesh(vertices, faces, labels,
              () if frozen is None else np.flatnonzero(np.asarray(frozen, bool)),
              exact, limit)
    m.set_guard(guard)
    budget = len(m.p) // 4 + 16  # most vertices the splits may add
    ar = aspect_ratios(vertices, faces)
    cand = {int(k): float(ar[k]) for k in np.flatnonzero(ar > bound)}
    history: list[int] = []
    current = True  # the mesh is in its best state
    best: tuple[int, list[Vec], list[list[int]], list[int], list[bool], list[float]] = (
        len(cand), list(m.p), [list(t) for t in m.f], list(m.lab), list(m.alive), list(m.dev))
    for _ in range(max_passes):
        if not cand:
            break
        history.append(len(cand))
        if len(history) > STALL_PASSES and \
                min(history[-STALL_PASSES:]) >= history[-STALL_PASSES - 1]:
            break  # no progress over STALL_PASSES passes
        m.dirty.clear()
        for k in sorted(cand, key=lambda k: -cand[k]):
            if m.added > budget:
                break
            if m.alive[k] and m.ar(k) > bound:
                m.fix(k, max_deviation)
        old, cand = cand, {}
        for k in m.dirty | set(old):
            if m.alive[k]:
                a = m.ar(k)
                if a > bound:
                    cand[k] = a
        current = len(cand) < best[0]
        if current:  # a later pass may split caps into more slivers
            best = (len(cand), list(m.p), [list(t) for t in m.f], list(m.lab), list(m.alive),
                    list(m.dev))
    return m if current else _best_mesh(m, best)


def _polish(m: _Mesh, bound: float, max_deviation: float) -> bool:
    """Trial edits (:meth:`_Mesh.polish`) on the triangles still above
    ``bound``, worst first, for ``POLISH_ROUNDS`` rounds: what the greedy
    order missed, each kept only where it helps; faces already beyond the
    exact-surface share may go up to the limit. True when the mesh changed."""
    m.relaxed = True
    changed = False
    for _ in range(POLISH_ROUNDS):
        live = np.flatnonzero(np.asarray(m.alive, bool))
        ar = aspect_ratios(np.asarray(m.p, np.float64), np.asarray(m.f, np.int64)[live])
        bad = [int(live[i]) for i in np.argsort(-ar, kind="stable") if ar[i] > bound]
        kept = [m.alive[k] and m.ar(k) > bound and m.polish(k, bound, max_deviation)
                for k in bad]
        if not any(kept):
            break
        changed = True
    m.relaxed = False
    return changed


def _arrays(m: _Mesh) -> tuple[FloatArray, IntArray, IntArray]:
    """The live faces of m as arrays (unused vertices dropped)."""
    keep = np.asarray(m.alive, bool)
    f = np.asarray(m.f, dtype=np.int64)[keep]
    lab = np.asarray(m.lab, dtype=np.int64)[keep]
    used, inv = np.unique(f, return_inverse=True)
    return np.asarray(m.p, np.float64)[used], inv.reshape(-1, 3).astype(np.int64), lab


def _best_mesh(m: _Mesh, best: tuple[int, list[Vec], list[list[int]], list[int], list[bool],
                                     list[float]]) -> _Mesh:
    """The pass's mesh put back into its best state (same vertex indices;
    the dead faces dropped)."""
    _, p, faces_, labs, alive, dev = best
    keep = [k for k, a in enumerate(alive) if a]
    out = _Mesh(np.asarray(p, np.float64).reshape(-1, 3), np.asarray([faces_[k] for k in keep]),
                np.asarray([labs[k] for k in keep]), m.frozen, m.exact, m.limit)
    out.dev = [dev[k] for k in keep]
    out.zone, out.zones, out.reach = m.zone, m.zones, m.reach
    return out


def _crossings(v: FloatArray, f: IntArray) -> IntArray:
    """(k, 2) face pairs that cross (exact finder) or that open3d's tolerant
    test takes for crossings; a pair may appear twice."""
    from .meshcheck import self_intersections, tolerant_intersections

    pairs = [self_intersections(v, f), tolerant_intersections(v, f)]
    return np.concatenate(pairs) if len(pairs[0]) + len(pairs[1]) else pairs[0]


def _fewer_slivers(v: FloatArray, f: IntArray, v0: FloatArray, f0: IntArray,
                   bound: float) -> bool:
    """Whether (v, f) has fewer triangles above ``bound`` than (v0, f0), or
    as many and a smaller worst aspect ratio."""
    a, a0 = aspect_ratios(v, f), aspect_ratios(v0, f0)
    n, n0 = int((a > bound).sum()), int((a0 > bound).sum())
    return n < n0 or (n == n0 and float(a.max()) < float(a0.max()))


def remove_slivers_checked(vertices: FloatArray, faces: IntArray, labels: IntArray, *,
                           bound: float, max_deviation: float, rounds: int = 6,
                           float32: bool = True, exact: Mapping[int, Implicit] | None = None,
                           limit: float = 0.0,
                           ) -> tuple[FloatArray, IntArray, IntArray]:
    """:func:`remove_slivers` that never makes two triangles cross.

    The pass's local checks (deviation, fold angle, link condition) do not
    see triangles that are near in space but far along the surface. After
    the pass, every pair of crossing triangles is found
    (:func:`tipgeo.meshcheck.self_intersections`, exact crossings and folds
    of adjacent triangles, and :func:`tipgeo.meshcheck.tolerant_intersections`,
    the near-coplanar pairs open3d's and MeshLab-style tolerant tests take
    for crossings); the pass is re-run from the input with the input
    vertices around the smaller triangle of each pair (within (round + 1) ×
    its longest edge) and those nearest the larger one's corners guarded —
    an edit whose new triangles touch them is made only when they cross
    nothing there —, for ``GUARD_ROUNDS`` rounds;
    after that, the input vertices around the smaller triangle of each pair
    left are frozen instead; until no pair is left or after ``rounds`` rounds.
    The result with the fewest pairs is kept when it has no more than
    the input had, else the input unchanged: the pass never adds a crossing.
    The trial edits (:func:`_polish`) run once, on that round's result
    (without them in the rounds, the rounds' crossings and guards are what
    they were), and are kept when they add no pair and leave fewer
    triangles above ``bound`` (or as many and a smaller worst).

    With ``float32`` (the default) the vertices returned are float32 values
    placed by :func:`snap_float32`, so that an STL (float32) stores them
    exactly and open3d's tolerant test finds on the file what it finds on
    the mesh.

    Parameters (``exact`` and ``limit`` too) and returns as
    :func:`remove_slivers` (mm, any frame).
    """
    from scipy.spatial import cKDTree

    vertices = np.asarray(vertices, np.float64)
    base = len(_crossings(vertices, faces))
    frozen = np.zeros(len(vertices), bool)
    tree: Any = None  # scipy has no types
    best: tuple[int, FloatArray, IntArray, IntArray] = (
        base, vertices, np.asarray(faces, np.int64), np.asarray(labels, np.int64))
    zones: list[IntArray] = []
    best_mesh: _Mesh | None = None
    for r in range(rounds):
        mesh = _passes(vertices, faces, labels, bound=bound, max_deviation=max_deviation,
                       max_passes=40, frozen=frozen, exact=exact, limit=limit, guard=zones)
        v, f, lab = _arrays(mesh)
        pairs = _crossings(v, f)
        if len(pairs) <= best[0]:
            best, best_mesh = (len(pairs), v, f, lab), mesh
        if len(pairs) == 0:
            break
        tree = cKDTree(vertices) if tree is None else tree
        for pair in np.unique(np.sort(pairs, axis=1), axis=0):
            t = v[f[pair]]
            edge = np.sqrt(((t - np.roll(t, 1, axis=1)) ** 2).sum(2)).max(1)
            k = int(np.argmin(edge))
            if r < GUARD_ROUNDS:  # edits there crossing-checked: around the smaller
                # triangle, and the larger one's corners (nearest input vertices)
                near = tree.query_ball_point(t[k].mean(0), (r + 1) * edge[k])
                corners = tree.query(t[1 - k])[1]
                zones.append(np.unique(np.r_[np.asarray(near, np.int64),
                                             np.asarray(corners, np.int64)]))
            else:  # around the smaller triangle: no edit at all
                frozen[tree.query_ball_point(t[k].mean(0), (r + 1 - GUARD_ROUNDS) * edge[k])] = True
    if best_mesh is not None and _polish(best_mesh, bound, max_deviation):
        v, f, lab = _arrays(best_mesh)  # the trial edits: kept when they cross nothing new
        pairs = _crossings(v, f)
        if len(pairs) <= best[0] and _fewer_slivers(v, f, best[1], best[2], bound):
            best = (len(pairs), v, f, lab)
    out = snap_float32(best[1], best[2]) if float32 else best[1]
    return out, best[2], best[3]


# -- float32 (STL) coordinates ------------------------------------------------

def _to32(x: FloatArray) -> FloatArray:
    """Rounded to the nearest float32, as float64."""
    out: FloatArray = np.asarray(x, np.float64).astype(np.float32).astype(np.float64)
    return out


def _moves(max_ulps: int) -> IntArray:
    """Candidate float32 steps (in ulps per axis) of the repair, the
    smallest first: along each axis up to ``max_ulps``, then ±1 on two and
    three axes at once."""
    out = [(0, 0, 0)]
    for k in range(1, max_ulps + 1):
        for ax in range(3):
            for sg in (-k, k):
                m = [0, 0, 0]
                m[ax] = sg
                out.append((m[0], m[1], m[2]))
    out += [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)
            if abs(a) + abs(b) + abs(c) >= 2]
    return np.asarray(out, np.int64)


def _incident(faces: IntArray, n: int) -> list[IntArray]:
    """The faces around each of the n vertices."""
    flat = np.asarray(faces, np.int64).ravel()
    order = np.argsort(flat, kind="stable")
    start = np.searchsorted(flat[order], np.arange(n + 1))
    fid = order // 3
    return [fid[start[i]:start[i + 1]] for i in range(n)]


def _best_move(w: FloatArray, faces: IntArray, near: tuple[IntArray, IntArray],
               x: int, star: IntArray, cands: FloatArray) -> tuple[int, FloatArray]:
    """The first candidate position of vertex x (they come smallest move
    first) that lowers the count of tolerant-test pairs around it: (the
    lowering, the position); (0, where it is) when none does."""
    from .meshcheck import count_tolerant

    old = w[x].copy()
    base = count_tolerant(w, faces, near, star)
    for c in cands:
        w[x] = c
        gain = base - count_tolerant(w, faces, near, star)
        if gain > 0:
            w[x] = old
            return gain, c.copy()
    w[x] = old
    return 0, old


def snap_float32(vertices: FloatArray, faces: IntArray, *, max_ulps: int | None = None,
                 rounds: int = 8) -> FloatArray:
    """Vertices as a binary STL stores them (float32), placed so that
    open3d's tolerant self-intersection test reports no pair that it did not
    on the full-precision mesh, where a few float32 steps allow.

    Rounding each coordinate to float32 (≈ 1e-7 of its size) tips coplanar
    faces (a flat cut face, one strip of a tessellated cylinder) out of their
    common plane by more than open3d's coplanarity tolerance, and its
    Möller test then takes neighbours in that plane for crossings. For every
    such pair (:func:`tipgeo.meshcheck.tolerant_intersections` on the rounded
    coordinates), each of its six vertices is tried at the float32 points up
    to ``max_ulps`` steps away along an axis (and one step on two or three
    axes) and the move that most lowers the count of pairs around that
    vertex is made; rounds repeat until none is left or no move helps.
    No vertex moves further than ``max_ulps`` float32 steps (≈ 1e-6 of its
    coordinates; default ``tol.float32_ulps``) nor than
    ``tol.float32_move_share`` of its shortest edge. Should the moves add an
    exact crossing (:func:`tipgeo.meshcheck.self_intersections`) to those of
    plain rounding, plain rounding is returned.

    Returns the (n, 3) vertices (float64 holding float32 values; mm, the
    input's frame).
    """
    from .meshcheck import near_pairs, self_intersections, tolerant_intersections

    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    w = _to32(v)
    pairs = tolerant_intersections(w, f)
    if not len(pairs):
        return w
    ulps = tol.float32_ulps if max_ulps is None else max_ulps
    step = np.spacing(np.abs(w).astype(np.float32)).astype(np.float64)  # (n, 3) mm
    t = v[f]
    edge = np.sqrt(((t - np.roll(t, 1, axis=1)) ** 2).sum(2))  # (m, 3)
    shortest = np.full(len(v), np.inf)
    for k in range(3):
        np.minimum.at(shortest, f[:, k], np.minimum(edge[:, k], edge[:, (k + 2) % 3]))
    limit = np.minimum(tol.float32_move_share * shortest, ulps * np.sqrt(3.0) * step.max(1))
    near = near_pairs(w, f, float(limit.max()) if len(limit) else 0.0)
    around = _incident(f, len(v))
    moves = _moves(ulps).astype(np.float64)
    for _ in range(rounds):
        gained = 0
        for a, b in pairs:
            for x in np.unique(np.concatenate([f[a], f[b]])):
                cands = _to32(w[x] + moves * step[x])  # w[x]: rounded at first
                ok = np.linalg.norm(cands - v[x], axis=1) <= limit[x]
                gain, pos = _best_move(w, f, near, int(x), around[x], cands[ok])
                if gain > 0:
                    w[x] = pos
                    gained += gain
                    break
        pairs = tolerant_intersections(w, f)
        if not len(pairs) or not gained:
            break
    # the moves are checked against the tolerant test only: keep them when
    # they add no exact crossing to what plain rounding has
    crossed = len(self_intersections(w, f))
    if crossed and crossed > len(self_intersections(_to32(v), f)):
        return _to32(v)
    return w
