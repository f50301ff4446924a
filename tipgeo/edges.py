"""Cutting edges of a tip: where the cut surfaces meet the outer and inner
walls, as ordered pieces parametrised by γ.

Analysis frame (thesis §3.1.2): the cannula frame turned about +z so that the
heel — the lowest point of the outer edge — lies at γ = 0, and shifted along
+z so that the heel is at z = 0. γ in rad, z and points in mm. (Where the
outer edge is flat, e.g. a conical tip, γ = 0 stays at the cannula's +x.)

Three ways to get an edge:

``exact``
    From the spec's cutters: z(γ) solved on the exact surface ∩ cylinder,
    tangents t ∝ n_c × n_s and normals n_s from the exact surface. Pieces
    split where the face forming the edge changes (kinks, e.g. multi-plane)
    and where the edge jumps vertically (serration sides).
``mesh``
    From a labelled mesh (built, simulated or imported): the mesh edges
    between wall and cut triangles, ordered into a loop, split into pieces
    where the adjacent cut face changes; normals from the mesh faces.
``fourier``
    Not an extraction: :mod:`tipgeo.angles` fits the points of either path
    with the thesis's Fourier series.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .arrays import AnyArray, ArrayLike, BoolArray, FloatArray, IntArray
from .cannula import Cannula
from .errors import SpecError, TipGeoError
from .tolerances import tol

if TYPE_CHECKING:  # pragma: no cover
    from .cutters.base import Cutter
    from .spec import TipSpec
    from .tip import Tip

__all__ = ["EdgePiece", "Edge", "Kink", "Jump", "exact_edges", "mesh_edges",
           "label_by_geometry", "heel_of", "lowest_cut", "rotate_z"]

#: Samples around a full turn for the exact path (pieces get their share).
DEFAULT_SAMPLES = 3600


@dataclass
class EdgePiece:
    """A smooth stretch of an edge formed by one face.

    Attributes
    ----------
    face : str — label (or face key) of the cut face
    gamma : (m,) float — rad, analysis frame, increasing
    z : (m,) float — mm from the heel
    tangent : (m, 3) float — unit, oriented towards increasing γ (None on
        the mesh path, where the Fourier fit gives it)
    normal : (m, 3) float — unit outward normal of the cut face
    """

    face: str
    gamma: FloatArray
    z: FloatArray
    tangent: FloatArray | None
    normal: FloatArray

    @property
    def span(self) -> tuple[float, float]:
        return float(self.gamma[0]), float(self.gamma[-1])


@dataclass
class Kink:
    """Where the edge passes from one face to another without a jump.

    ``theta`` is the included angle between the two faces there,
    π − arccos(n_a · n_b) (eq. 2.3 for a symmetric multi-plane tip)."""

    gamma: float
    z: float
    faces: tuple[str, str]
    theta: float


@dataclass
class Jump:
    """A vertical stretch of the edge (not single-valued in γ): at ``gamma``
    the edge runs from ``z0`` to ``z1`` along the wall."""

    gamma: float
    z0: float
    z1: float
    faces: tuple[str, str]


@dataclass
class Edge:
    """One cutting edge (outer or inner wall).

    Attributes
    ----------
    wall : str — ``outer`` or ``inner``
    radius : float — mm
    pieces : list of EdgePiece — in order of γ over [0, 2π)
    kinks, jumps : lists
    method : str — ``exact`` or ``mesh``
    heel : (float, float) — cannula-frame γ and z of the heel (rad, mm)
    """

    wall: str
    radius: float
    pieces: list[EdgePiece]
    kinks: list[Kink] = field(default_factory=list)
    jumps: list[Jump] = field(default_factory=list)
    method: str = "exact"
    heel: tuple[float, float] = (0.0, 0.0)

    @property
    def gamma(self) -> FloatArray:
        return np.concatenate([p.gamma for p in self.pieces])

    @property
    def z(self) -> FloatArray:
        return np.concatenate([p.z for p in self.pieces])

    @property
    def points(self) -> FloatArray:
        """(m, 3) edge points in the analysis frame (mm)."""
        g, z = self.gamma, self.z
        return np.stack([self.radius * np.cos(g), self.radius * np.sin(g), z], 1)


# -----------------------------------------------------------------------------
# exact path
def lowest_cut(cutters: Sequence[Cutter], gamma: ArrayLike, radius: float | FloatArray,
               cannula: Cannula) -> tuple[FloatArray, AnyArray, IntArray]:
    """The lowest cut surface over each γ on the cylinder of ``radius`` (mm,
    or one radius per γ; γ in rad, cannula frame): (z (mm), face key, index
    of the cutter)."""
    g = np.atleast_1d(np.asarray(gamma, float))
    zbest = np.full(g.shape, np.inf)
    face = np.full(g.shape, "", dtype=object)
    owner = np.full(g.shape, -1)
    for k, c in enumerate(cutters):
        r = c.edge_faces(g, radius, cannula, tuple(cutters[:k]))
        if r is None:
            raise SpecError(f"cutter '{c.name}' ({c.kind}) has no exact description; use "
                            "method='mesh' on a built tip")
        z, f = r
        better = z < zbest
        zbest = np.where(better, z, zbest)
        face = np.where(better, f, face)
        owner = np.where(better, k, owner)
    if not np.all(np.isfinite(zbest)):
        raise TipGeoError("no cutter crosses the wall everywhere; the edge is undefined")
    return zbest, face, owner


def heel_of(cutters: Sequence[Cutter], cannula: Cannula) -> tuple[float, float]:
    """Cannula-frame (γ, z) of the outer edge's lowest point (rad, mm)."""
    r = cannula.r_o
    g = np.linspace(0.0, 2 * np.pi, 7200, endpoint=False)
    z, _, _ = lowest_cut(cutters, g, r, cannula)
    if z.max() - z.min() < tol.level:
        return 0.0, float(z.min())
    low = np.flatnonzero(z <= z.min() + tol.heel_tie)  # equal heels: the one nearest γ = 0
    k = int(low[np.argmin(np.abs(np.angle(np.exp(1j * g[low]))))])
    lo, hi = g[k] - 2 * np.pi / 7200, g[k] + 2 * np.pi / 7200
    for _ in range(90):
        a = hi - 0.6180339887498949 * (hi - lo)
        b = lo + 0.6180339887498949 * (hi - lo)
        za, zb = lowest_cut(cutters, np.array([a, b]), r, cannula)[0]
        if za < zb:
            hi = b
        else:
            lo = a
    gh = _flat_point(cutters, cannula, r, 0.5 * (lo + hi), hi - lo)
    zh = float(lowest_cut(cutters, np.array([gh]), r, cannula)[0][0])
    if zh > z[k]:  # a kink minimum: the sample is the better estimate
        gh, zh = float(g[k]), float(z[k])
    return float(np.mod(gh, 2 * np.pi)), zh


def _dz(cutters: Sequence[Cutter], cannula: Cannula, r: float, g: FloatArray) -> FloatArray:
    """Exact z′(γ) = −r n_γ / n_z on the cylinder of radius r."""
    z, _, owner = lowest_cut(cutters, g, r, cannula)
    pts = np.stack([r * np.cos(g), r * np.sin(g), z], 1)
    out = np.empty(len(g))
    for k in np.unique(owner):
        s = owner == k
        n = cutters[k].normals(pts[s], cannula, tuple(cutters[:k]))
        ng = -np.sin(g[s]) * n[:, 0] + np.cos(g[s]) * n[:, 1]
        out[s] = -r * ng / n[:, 2]
    return out


def _flat_point(cutters: Sequence[Cutter], cannula: Cannula, r: float, g0: float,
                width: float) -> float:
    """Refine a smooth minimum of z(γ) to z′(γ) = 0 by bisection (the golden
    section alone stops at √ε ≈ 1e-8 rad)."""
    a, b = g0 - 2 * width - tol.bracket_pad, g0 + 2 * width + tol.bracket_pad
    da, db = _dz(cutters, cannula, r, np.array([a, b]))
    if not (da < 0 < db):
        return g0
    for _ in range(60):
        m = 0.5 * (a + b)
        dm = _dz(cutters, cannula, r, np.array([m]))[0]
        if dm < 0:
            a = m
        else:
            b = m
    return 0.5 * (a + b)


def _breaks(cutters: Sequence[Cutter], radius: float, cannula: Cannula, g0: float,
            n: int) -> FloatArray:
    """Face changes around the wall: sorted cannula-frame γ (rad), refined
    by bisection to 1e-13 rad."""
    g = g0 + np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    _, face, _ = lowest_cut(cutters, g, radius, cannula)
    nxt = np.roll(face, -1)
    idx = np.flatnonzero(face != nxt)
    if len(idx) == 0:
        return np.array([])
    lo = g[idx]
    hi = lo + 2 * np.pi / n
    f_lo = face[idx]
    for _ in range(46):
        mid = 0.5 * (lo + hi)
        _, fm, _ = lowest_cut(cutters, mid, radius, cannula)
        same = fm == f_lo
        lo = np.where(same, mid, lo)
        hi = np.where(same, hi, mid)
    return np.sort(np.mod(0.5 * (lo + hi) - g0, 2 * np.pi)) + g0


def exact_edges(spec: TipSpec, *, samples: int = DEFAULT_SAMPLES) -> tuple[Edge, Edge]:
    """Outer and inner edges of ``spec`` on the exact surfaces.

    Parameters
    ----------
    spec : TipSpec
    samples : int — points per full turn (pieces get their share, ≥ 24 each)

    Returns
    -------
    (outer, inner) : Edge, Edge — analysis frame (heel at γ = 0, z = 0)
    """
    cannula, cutters = spec.cannula, tuple(spec.cutters)
    gh, zh = heel_of(cutters, cannula)
    out = []
    for wall, r in (("outer", cannula.r_o), ("inner", cannula.r_i)):
        out.append(_exact_wall(cutters, cannula, wall, r, gh, zh, samples))
    return out[0], out[1]


def _exact_wall(cutters: Sequence[Cutter], cannula: Cannula, wall: str, r: float, gh: float,
                zh: float, samples: int) -> Edge:
    eps = tol.break_gap  # pieces stop this short of a break (rad)
    br = _breaks(cutters, r, cannula, gh, max(samples, 720))
    # pieces run between face changes (one piece may wrap past the heel)
    bounds = np.append(br, br[0] + 2 * np.pi) if len(br) else np.array([gh, gh + 2 * np.pi])
    pieces: list[EdgePiece] = []
    kinks: list[Kink] = []
    jumps: list[Jump] = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a <= 4 * eps:
            continue
        m = max(24, int(math.ceil(samples * (b - a) / (2 * np.pi))))
        g = np.linspace(a + eps, b - eps, m + 1)
        z, face, owner = lowest_cut(cutters, g, r, cannula)
        k = int(owner[m // 2])
        key = face[m // 2]
        if np.any(face != key):  # a face change the sampling missed: split again
            raise TipGeoError(f"edge on the {wall} wall: faces change inside a piece near "
                              f"γ = {math.degrees(a - gh):.4f}°; raise samples")
        pts = np.stack([r * np.cos(g), r * np.sin(g), z], 1)
        n = cutters[k].normals(pts, cannula, tuple(cutters[:k]))
        e_g = np.stack([-np.sin(g), np.cos(g), np.zeros_like(g)], 1)
        nz = n[:, 2]
        ng = np.einsum("ij,ij->i", n, e_g)
        t = nz[:, None] * e_g - ng[:, None] * np.array([0.0, 0.0, 1.0])
        t *= np.sign(nz)[:, None]
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        pieces.append(EdgePiece(str(key), g - gh, z - zh, rotate_z(t, -gh), rotate_z(n, -gh)))
    # kinks and jumps between consecutive pieces (cyclic)
    for p, q in zip(pieces, pieces[1:] + pieces[:1]):
        gq = q.gamma[0] if q is not pieces[0] else q.gamma[0] + 2 * np.pi
        zp, zq = p.z[-1], q.z[0]
        if len(pieces) == 1:
            break
        if p.face == q.face and abs(zp - zq) < tol.join:
            continue
        gb = 0.5 * (p.gamma[-1] + gq)
        if abs(zp - zq) < tol.join:
            cos = float(np.clip(p.normal[-1] @ q.normal[0], -1, 1))
            kinks.append(Kink(float(np.mod(gb, 2 * np.pi)), float(0.5 * (zp + zq)),
                              (p.face, q.face), math.pi - math.acos(cos)))
        else:
            jumps.append(Jump(float(np.mod(gb, 2 * np.pi)), float(zp), float(zq),
                              (p.face, q.face)))
    return Edge(wall, r, pieces, kinks, jumps, "exact", (gh, zh))


def rotate_z(v: FloatArray, a: float) -> FloatArray:
    """Vectors (n, 3) rotated by ``a`` (rad) about +z (cannula frame)."""
    c, s = math.cos(a), math.sin(a)
    out = v.copy()
    out[:, 0] = c * v[:, 0] - s * v[:, 1]
    out[:, 1] = s * v[:, 0] + c * v[:, 1]
    return out


# -----------------------------------------------------------------------------
# mesh path
def _loop(tip: Tip, wall: str) -> tuple[IntArray, IntArray]:
    """Mesh edges between ``wall`` triangles and cut triangles, as one
    ordered loop: (vertex ids (k,), cut triangle per segment (k,))."""
    faces = tip.faces
    labels = tip.labels
    is_wall = labels == wall
    is_cut = np.array([str(x).startswith("cut:") for x in labels])
    # directed half-edges of cut triangles, keyed by undirected edge
    he = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 3, 2)
    wall_edges: dict[tuple[int, int], int] = {}
    for t in np.flatnonzero(is_wall):
        for a, b in he[t]:
            wall_edges[(int(min(a, b)), int(max(a, b)))] = int(t)
    seg = []
    for t in np.flatnonzero(is_cut):
        for a, b in he[t]:
            key = (int(min(a, b)), int(max(a, b)))
            if key in wall_edges:
                seg.append((int(a), int(b), int(t)))
    if not seg:
        raise TipGeoError(f"no edge between the {wall} wall and a cut face")
    nxt: dict[int, list[tuple[int, int]]] = {}
    for a, b, tri in seg:
        nxt.setdefault(a, []).append((b, tri))
    start = seg[0][0]
    order, tris = [start], []
    cur = start
    for _ in range(len(seg)):
        b, tri = nxt[cur][0]
        tris.append(tri)
        if b == start:
            break
        order.append(b)
        cur = b
    if len(tris) != len(seg):
        raise TipGeoError(f"the {wall} edge is not a single closed loop "
                          f"({len(tris)} of {len(seg)} segments)")
    return np.array(order), np.array(tris)


def mesh_edges(tip: Tip, *, radii: tuple[float, float] | None = None) -> tuple[Edge, Edge]:
    """Outer and inner edges of a labelled tip mesh (cannula frame in,
    analysis frame out: heel at γ = 0, z = 0).

    ``radii`` (r_o, r_i) default to the tip's spec; needed for imported
    meshes (see :func:`label_by_geometry`)."""
    if radii is None:
        if tip.spec is None:
            raise SpecError("radii = None: give (r_o, r_i) in mm for a tip without a spec")
        radii = (tip.spec.cannula.r_o, tip.spec.cannula.r_i)
    loops = {}
    for wall in ("outer", "inner"):
        vid, tris = _loop(tip, wall)
        loops[wall] = (vid, tris)
    v = tip.vertices
    vo = v[loops["outer"][0]]
    zo = vo[:, 2]
    if zo.max() - zo.min() < tol.level:
        gh, zh = 0.0, float(zo.min())
    else:
        # the lowest vertex; among equal ones (multi-plane heels) the nearest γ = 0
        low = np.flatnonzero(zo <= zo.min() + tol.level)
        k = int(low[np.argmin(np.abs(np.arctan2(vo[low, 1], vo[low, 0])))])
        gh, zh = float(np.arctan2(vo[k, 1], vo[k, 0])), float(zo[k])
    fn = tip.face_normals
    out = []
    for wall, r in zip(("outer", "inner"), radii):
        vid, tris = loops[wall]
        p = v[vid]
        g = np.mod(np.arctan2(p[:, 1], p[:, 0]) - gh, 2 * np.pi)
        seg_face = tip.labels[tris]
        seg_n = rotate_z(fn[tris], -gh)
        # orient the loop by increasing γ
        dg = np.angle(np.exp(1j * (np.roll(g, -1) - g)))
        if np.sum(dg) < 0:
            vid, tris = vid[::-1], np.roll(tris[::-1], -1)
            p, g = p[::-1], g[::-1]
            seg_face = seg_face[::-1]
            seg_face = np.roll(seg_face, -1)
            seg_n = np.roll(seg_n[::-1], -1, axis=0)
        # start at the smallest γ
        s = int(np.argmin(g))
        idx = np.roll(np.arange(len(g)), -s)
        g, z = g[idx], p[idx, 2] - zh
        seg_face, seg_n = seg_face[idx], seg_n[idx]
        out.append(_mesh_pieces(wall, r, g, z, seg_face, seg_n, (gh, zh)))
    return out[0], out[1]


def _mesh_pieces(wall: str, r: float, g: FloatArray, z: FloatArray, seg_face: AnyArray,
                 seg_n: FloatArray, heel: tuple[float, float]) -> Edge:
    """Split the ordered loop (segment i joins vertex i to i + 1) into runs of
    one face; vertical segments become jumps."""
    gv = np.append(g, g[0] + 2 * np.pi)
    zv = np.append(z, z[0])
    dg = np.diff(gv)
    if np.any(dg < -tol.angle):
        raise TipGeoError(f"the {wall} edge turns back in γ; it is not a single loop "
                          "around the axis")
    vertical = dg < tol.angle
    keys = [(str(f), bool(vv)) for f, vv in zip(seg_face, vertical)]
    runs: list[tuple[int, int]] = []
    s0 = 0
    for i in range(1, len(keys) + 1):
        if i == len(keys) or keys[i] != keys[s0]:
            runs.append((s0, i - 1))
            s0 = i
    kinks: list[Kink] = []
    items: list[_MeshPiece | Jump] = []
    for s_, e_ in runs:
        face, vert = keys[s_]
        if vert:
            items.append(Jump(float(gv[s_]), float(zv[s_]), float(zv[e_ + 1]), (face, face)))
        else:
            items.append(_MeshPiece(face, gv[s_:e_ + 2].copy(), zv[s_:e_ + 2].copy(), None,
                                    seg_n[s_:e_ + 1].copy()))
    # a face that wraps past γ = 0 is one piece
    last, first = items[-1], items[0]
    if (len(items) > 1 and isinstance(first, _MeshPiece) and isinstance(last, _MeshPiece)
            and first.face == last.face):
        items.pop()
        items[0] = _MeshPiece(first.face, np.concatenate([last.gamma[:-1] - 2 * np.pi,
                                                          first.gamma]),
                              np.concatenate([last.z[:-1], first.z]), None,
                              np.concatenate([last.normal, first.normal]))
    pieces: list[EdgePiece] = [x for x in items if isinstance(x, _MeshPiece)]
    jumps = [x for x in items if isinstance(x, Jump)]
    for p, q in zip(pieces, pieces[1:] + pieces[:1]):
        if p.face != q.face and abs(p.z[-1] - q.z[0]) < tol.join:
            cos = float(np.clip(p.normal[-1] @ q.normal[0], -1, 1))
            kinks.append(Kink(float(np.mod(p.gamma[-1], 2 * np.pi)), float(p.z[-1]),
                              (p.face, q.face), math.pi - math.acos(cos)))
    return Edge(wall, r, pieces, kinks, jumps, "mesh", heel)


@dataclass
class _MeshPiece(EdgePiece):
    """A mesh piece: vertices (gamma, z) and one normal per segment."""

    def normal_at(self, gamma: FloatArray) -> FloatArray:
        """The normal of the segment containing each γ."""
        k = np.clip(np.searchsorted(self.gamma, gamma, side="right") - 1, 0,
                    len(self.normal) - 1)
        return self.normal[k]


# -----------------------------------------------------------------------------
def label_by_geometry(tip: Tip, *, r_o: float, r_i: float,
                      axis_point: ArrayLike = (0.0, 0.0, 0.0),
                      axis_dir: ArrayLike = (0.0, 0.0, 1.0), radial_tol: float | None = None,
                      crease_deg: float = 10.0) -> Tip:
    """Label an imported (unlabelled) tip by its geometry.

    The mesh is moved into the cannula frame (``axis_point`` to the origin,
    ``axis_dir`` — pointing to the tip — onto +z) and every triangle is
    labelled ``outer`` / ``inner`` (all corners within ``radial_tol`` of r_o /
    r_i and the normal radial, outwards / inwards), ``base`` (facing −z at the
    lowest z) or ``cut:face<k>`` — cut triangles grouped into smooth faces
    that meet at creases sharper than ``crease_deg``.

    Returns a new :class:`Tip` (mm, cannula frame, z origin unchanged).
    """
    from .tip import Tip

    d = np.asarray(axis_dir, float)
    if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
        raise SpecError(f"axis_dir = {axis_dir!r} is not a non-zero 3-vector")
    d = d / np.linalg.norm(d)
    x = np.cross(d, [0.0, 1.0, 0.0]) if abs(d[1]) < 0.9 else np.cross(d, [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(d, x)
    basis = np.stack([x, y, d])
    v = (tip.vertices - np.asarray(axis_point, float)) @ basis.T
    f = tip.faces
    tol_r = radial_tol if radial_tol is not None else tol.radial_ratio * (r_o - r_i)
    tri = v[f]
    rho = np.hypot(tri[..., 0], tri[..., 1])
    cen = tri.mean(axis=1)
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), tol.tiny)
    er = cen[:, :2] / np.maximum(np.hypot(cen[:, 0], cen[:, 1]), tol.tiny)[:, None]
    radial = np.einsum("ij,ij->i", nrm[:, :2], er)
    outer = np.all(np.abs(rho - r_o) <= tol_r, axis=1) & (radial > 0.99)
    inner = np.all(np.abs(rho - r_i) <= tol_r, axis=1) & (radial < -0.99)
    zmin = v[:, 2].min()
    base = (nrm[:, 2] < -0.99) & np.all(np.abs(tri[..., 2] - zmin) <= tol_r, axis=1)
    cut = ~(outer | inner | base)
    names = ["outer", "inner", "base"]
    ids = np.where(outer, 0, np.where(inner, 1, 2))
    # group cut triangles into smooth faces
    comp = _smooth_components(f, nrm, cut, math.radians(crease_deg))
    for k, c in enumerate(sorted(set(comp[cut].tolist()))):
        names.append(f"cut:face{k}")
        ids[comp == c] = len(names) - 1
    return Tip(v, f, ids, tuple(names), spec=None, tolerance=tip.tolerance,
               segments=None, source=tip.source, meta=dict(tip.meta))


def _smooth_components(faces: IntArray, normals: FloatArray, mask: BoolArray,
                       crease: float) -> IntArray:
    """(m,) int — per triangle its smooth face: the smallest triangle index
    of its component (triangles of ``mask`` sharing an edge across which
    the normals turn by less than ``crease`` rad), −1 off ``mask``."""
    m = len(faces)
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    t = np.repeat(np.arange(m), 3)
    order = np.lexsort((e[:, 1], e[:, 0]))
    e, t = e[order], t[order]
    same = np.all(e[1:] == e[:-1], axis=1)
    a, b = t[:-1][same], t[1:][same]
    ok = mask[a] & mask[b] & (np.einsum("ij,ij->i", normals[a], normals[b]) > math.cos(crease))
    comp = _components(m, a[ok], b[ok])
    comp = np.where(mask, comp, -1)
    return comp


def _components(m: int, a: IntArray, b: IntArray) -> IntArray:
    """Connected components of the undirected graph on nodes 0..m−1 with
    edges (a, b): per node the smallest node index of its component (min-
    label propagation with pointer jumping; no scipy.sparse import, which
    costs the CLI a tenth of a second)."""
    lab = np.arange(m)
    while True:
        low = np.minimum(lab[a], lab[b])
        new = lab.copy()
        np.minimum.at(new, a, low)
        np.minimum.at(new, b, low)
        new = new[new]
        if np.array_equal(new, lab):
            return lab
        lab = new
