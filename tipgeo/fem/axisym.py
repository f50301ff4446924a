"""The 2D axisymmetric insertion model (thesis §4.4.1.2, Appendix B2) of any
axisymmetric tip.

Frame and units: model frame of :mod:`tipgeo.fem.model` — X = radius,
needle along −Y, block top at Y = 0; mm. The needle's section comes from the
tip (:func:`~tipgeo.fem.profile.wall_profile`), mapped by X = r,
Y = z_max − z and kept from its most advanced point back to ``depth`` +
``needle_margin`` behind it. The block is the thesis's r = 7 mm × 7 mm with
its base fixed and its axis held radially; the other faces are free.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import validate as v
from ..arrays import ArrayLike, FloatArray, IntArray
from ..errors import SpecError
from ..tip import Tip
from ..tolerances import tol
from .material import DEFAULT_NU, fem_material, model_friction
from .mesh import mesh_2d
from .model import (
    FACE_NODES,
    UM_PER_MM,
    ElementBlock,
    FemModel,
    boundary_faces,
    check_output_depths,
    contact_penalty,
)
from .profile import clip_profile, round_corners, wall_profile

__all__ = ["axisymmetric_model", "auto_slave", "BLOCK_2D", "AXISYMMETRIC_FORCE_SCALE", "CUTS"]

#: Cut models of the axisymmetric insertion (see ``cut``).
CUTS = ("none", "erosion")

#: Block radius and height of the thesis's 2D model (§4.4.1.2), mm.
BLOCK_2D = (7.0, 7.0)

#: CalculiX expands axisymmetric elements to 2° wedges: whole ring = 180 ×.
AXISYMMETRIC_FORCE_SCALE = 180.0

#: Edge radius r_tip of the thesis's biopsy punch (Fig. 4.7), mm.
EDGE_RADIUS = 0.015

#: Largest default needle advance per increment, mm.
MAX_STEP = 0.05

#: Default depth (mm) down to which the contact zone is meshed fine and the
#: needle's section is kept: the mesh depends on the element size and the
#: block, never on the depth asked for (a depth ladder runs on one mesh).
FINE_DEPTH = 3.0

#: Default pre-distortion of the tissue under the needle's front (issue 28):
#: its elements start ``CRUSH_ASPECT`` × h tall at the top (h wide), graded
#: to h at ``CRUSH_DEPTH`` mm, so that the tissue the front crushes (a
#: smallest principal stretch of 0.5–0.3 along the axis) is near square when
#: crushed; with it the default mesh reaches 3 mm (docs/notes/fem-depth.md).
CRUSH_ASPECT = 3.0
CRUSH_DEPTH = 0.5

#: The friction's stick slope as a fraction of the normal penalty stiffness
#: (tangential stiffness before slip; 1 was the earlier default, whose
#: stick–slip toggling of the nodes under the front stalled ccx).
STICK_RATIO = 0.1

#: Whose nodes are the contact's slaves (``slave``).
SLAVES = ("auto", "tissue", "needle")

#: ``slave="auto"`` makes the tissue's nodes slaves when the needle's front
#: (the land between its rounded corners) is at least this many elements
#: wide, else the needle's: with fewer tissue nodes across it the front
#: slips between them (measured: at 100 µm the 64 µm land of the punch goes
#: through the tissue's faces by 1.2 mm, the force falling 30 %).
SLAVE_TISSUE_ELEMENTS = 2.0

#: Limits on the model size, checked before meshing (elements).
MAX_ELEMENTS = 400_000

#: Smallest element size and cut step (mm): 1 µm.
MIN_ELEMENT_MM = 0.001

#: Floor of the smallest increment as a needle advance (mm): 1 nm.
MIN_INCREMENT_MM = 1e-6


def _estimate_elements(h: float, band: float, grade: float, h_far: float,
                       depth: float, R: float, H: float) -> float:
    near = band * (depth + band) / h ** 2
    mid = 2 * grade * (depth + grade) / ((h + h_far) / 2) ** 2
    return near + mid + R * H / h_far ** 2


def axisymmetric_model(tip: Tip, *, depth: float, tissue: str = "pvc-sp0",
                       material_model: str = "arruda-boyce", nu: float = DEFAULT_NU,
                       friction: float | None = None, mesh: float = 0.02,
                       block: tuple[float, float] = BLOCK_2D,
                       output_depths: tuple[float, ...] = (),
                       max_increment: float | None = None,
                       penalty_factor: float = 50.0, edge_radius: float = EDGE_RADIUS,
                       contact: str = "node", nose_refine: float = 1.0,
                       far: float | None = None,
                       contact_stiffness: float | None = None, cut: str = "none",
                       cut_step: float | None = None, cut_lead: int = 1,
                       fine_depth: float | None = None,
                       crush_aspect: float = CRUSH_ASPECT, crush_depth: float = CRUSH_DEPTH,
                       slave: str = "auto", stick_ratio: float | None = None) -> FemModel:
    """The axisymmetric insertion model of ``tip`` pushed ``depth`` into a
    tissue block.

    Parameters
    ----------
    tip : Tip — an axisymmetric tip (conical cutters or none)
    depth : float — needle travel, mm (0 < depth ≤ 0.8 × block height)
    tissue : str — a tissue of :func:`tipgeo.mechanics.tissue_names`
    material_model : ``arruda-boyce`` | ``ogden`` | ``neo-hookean``
    nu : float — Poisson ratio (thesis 2D: 0.475)
    friction : float, optional — Coulomb coefficient; default the tissue's
        regression at k = 0 (Table 4.2 for S/P = 0: μ_da(0) = 0.328)
    mesh : float — element size h in the contact zone, mm
    block : (R, H) — block radius and height, mm
    output_depths : depths (mm) at which stresses are written
    max_increment : float, optional — largest needle advance per increment,
        mm (default min(:data:`MAX_STEP`, 2h)); the first increment advances
        min(this, h / 10). Both are needle advances in mm, whatever the depth:
        runs to different depths take the same increments where they overlap
    penalty_factor : float — contact stiffness = this × E₀ / h (MPa/mm)
    edge_radius : float — the sharp corners of the section's front are
        rounded to this radius, mm (default 15 µm, the r_tip of Fig. 4.7;
        0 keeps them sharp, which ccx's contact handles badly)
    contact : ``node`` (node-to-surface) | ``surface`` (surface-to-surface)
    slave : ``auto`` (default: ``tissue`` when the needle's front is at
        least :data:`SLAVE_TISSUE_ELEMENTS` elements wide, else ``needle``)
        | ``tissue`` (the tissue's nodes slave to the needle's faces: the
        rigid needle is the master; its corners reach up to about h into the
        facets of the tissue between two nodes) | ``needle`` (the needle's
        nodes slave to the tissue's faces, as before issue 28: the narrow
        front cannot slip between tissue nodes, but the nodes under it
        stall ccx between 0.7 and 1.6 mm on the default mesh). The erosion
        cut always has the tissue's nodes slave
    stick_ratio : float, optional — the friction's stick slope (tangential
        stiffness before slip) as a fraction of the contact's penalty
        stiffness (0 < ratio ≤ 1; default :data:`STICK_RATIO`, and 1 — as
        before issue 28 — for the erosion cut)
    crush_aspect : float — the tissue under the needle's front (the land's
        radii ± h, down to ``crush_depth``) is a structured column of
        elements h wide whose height grows geometrically from h at its
        bottom to this × h at the top, so that they are near square once the
        front has crushed them (1: no column, the free mesh; 1–8; default
        :data:`CRUSH_ASPECT`). The erosion cut has its own column instead
    crush_depth : float — the depth of that column, mm (default
        :data:`CRUSH_DEPTH`)
    nose_refine : float — the tissue just under the needle's front (within
        2h of it, 3h deep: what wraps around the edge) gets h / this

    far : float, optional — element size far from the contact zone, mm
        (default min(0.5, max(10 h, 0.25)))
    contact_stiffness : float, optional — the penalty stiffness itself,
        MPa/mm (overrides ``penalty_factor``; a convergence study holds it
        fixed so that only the mesh changes)
    cut : ``none`` (one continuous block: the tissue under the needle's
        front can only wrap around it — the thesis's Abaqus model remeshes
        adaptively, CalculiX cannot, so its elements there crush within
        about 1 mm) | ``erosion`` (a predefined cut path with element
        deletion: the column of tissue between the front's inner and outer
        radii is a structured mesh of layers ``cut_step`` thick; the needle
        advances ``cut_step`` per step and each step first removes the
        layers the front has reached, ``*MODEL CHANGE``, and moves the
        needle's contact onto the faces that become exposed)
    cut_step : float, optional — erosion: needle advance per step and layer
        thickness, mm (default ``mesh``)
    cut_lead : int — erosion: step k (front from d_(k−1) to d_k) removes the
        layers whose top lies above d_(k−1) + ``cut_lead`` layers (0: only
        the layers the front has passed; 1: also the one it enters)
    fine_depth : float, optional — the contact zone is meshed at h down to
        this depth plus a pad, and the needle's section is kept this long
        plus a margin, mm (default max(:data:`FINE_DEPTH`, depth), at most
        0.8 × the block height): the mesh is the same for every depth up to
        it, so a depth ladder (or a run that stops early) uses one mesh

    Returns
    -------
    FemModel with ``force_scale`` 180 (the 2° wedge to the whole ring)
    """
    R, H = (v.length("block radius", block[0]), v.length("block height", block[1]))
    depth = v.real("depth", depth, lo=0.0, hi=0.8 * H, lo_open=True, unit="mm")
    h = v.real("mesh", mesh, lo=MIN_ELEMENT_MM, hi=0.5, unit="mm")
    prof, needle, r_e = _needle_section(tip, R, H, depth, edge_radius)
    z = _zones(needle, R=R, H=H, depth=depth, h=h, far=far, nose_refine=nose_refine,
               fine_depth=fine_depth)
    if cut not in CUTS:
        raise SpecError(f"cut = {cut!r} is not valid; expected one of: " + ", ".join(CUTS))
    stick = _stick_ratio(slave, stick_ratio, cut)
    column, dz, lead, grading = None, 0.0, 0, 1.0
    if cut == "erosion":
        column, dz, lead = _erosion_column(needle, H=H, depth=depth, h=h, r_e=r_e,
                                           cut_step=cut_step, cut_lead=cut_lead)
    else:
        column, grading = _crush_column(z, h=h, H=H, aspect=crush_aspect, depth=crush_depth)
    nodes, parts = mesh_2d(needle, block=(R, H), boxes=[(z.box, h), (z.nose, z.h_nose)],
                           h_far=z.h_far, grade=z.grade, column=column, grading=grading)
    blocks, eid = [], 1
    for part in ("tissue", "needle"):
        for et, conn in sorted(parts[part].items()):
            blocks.append(ElementBlock(et, part, np.arange(eid, eid + len(conn)), conn))
            eid += len(conn)
    eps = tol.fem.plane_rel * R
    tb = [b for b in blocks if b.part == "tissue"]
    nb = [b for b in blocks if b.part == "needle"]
    surfaces = _contact_surfaces(nodes, tb, nb, float(needle[:, 1].max()), eps)
    tissue_nodes = np.unique(np.concatenate([b.conn.ravel() for b in tb]))
    tn = nodes[tissue_nodes - 1]
    nsets = {"BASE": tissue_nodes[np.abs(tn[:, 1] + H) <= eps],
             "AXIS": tissue_nodes[np.abs(tn[:, 0]) <= eps],
             "NEEDLE": np.unique(np.concatenate([b.conn.ravel() for b in nb]))}
    mat = fem_material(tissue, material_model, nu)
    mu, mu_src = model_friction(tissue, friction)
    d0, dmax = _increments(h, depth, max_increment)
    out = check_output_depths(output_depths, depth)
    info = {"element_size_um": round(h * UM_PER_MM, 6),
            "element_size_far_um": round(z.h_far * UM_PER_MM, 6),
            "element_size_front_um": round(z.h_nose * UM_PER_MM, 6),
            "fine_zone_mm": [round(x, 6) for x in z.box], "nodes": len(nodes),
            "tissue_elements": int(sum(len(b.ids) for b in tb)),
            "needle_elements": int(sum(len(b.ids) for b in nb)),
            "block_mm": [R, H], "edge_r_mm": [z.r_lo, z.r_hi], "tip": tip.spec.name if tip.spec
            else "imported", "tissue": mat.name, "material": mat.model,
            "material_source": mat.source, "edge_radius_um": round(r_e * UM_PER_MM, 6),
            "inner_diameter_mm": 2 * float(prof[:, 0].min()),
            "_needle_section": needle.tolist(), "contact": contact, "nu": nu, "friction": mu,
            "friction_source": mu_src, "fine_depth_mm": round(z.d_fine, 9),
            "first_increment_mm": round(d0, 9), "max_increment_mm": round(dmax, 9)}
    if column is not None and cut != "erosion":
        info.update(_crush_info(column, crush_aspect, grading))
    stages: tuple[tuple[float, IntArray, str], ...] = ()
    node_surfaces: dict[str, IntArray] = {}
    if cut == "erosion" and column is not None:
        stages, node_surfaces = _erosion_stages(nodes, tb, column, dz, lead, depth, out,
                                                surfaces, eps)
        info.update({"cut": cut, "cut_step_um": round(dz * UM_PER_MM, 6), "cut_lead": lead,
                     "cut_r_mm": [column[0], column[1]], "steps": len(stages)})
    penalty = contact_penalty(penalty_factor, mat.E0, h, contact_stiffness)
    slave = _slave(slave, bool(stages), needle, h)
    info.update({"slave": slave, "stick_slope_MPa_per_mm": round(stick * penalty, 9)})
    return FemModel(kind="axisymmetric", name=info["tip"], nodes=nodes, blocks=blocks,
                    nsets=nsets, fixed={"BASE": (1, 2), "AXIS": (1,)}, stages=stages,
                    node_surfaces=node_surfaces,
                    surfaces=surfaces, material=mat, friction=mu,
                    depth=depth, penalty=penalty, stick_slope=stick * penalty,
                    force_scale=AXISYMMETRIC_FORCE_SCALE,
                    # a 1 nm floor on the smallest increment
                    increments=(d0 / depth, MIN_INCREMENT_MM * min(1.0, 1.0 / depth),
                                dmax / depth),
                    output_depths=out, contact=contact, slave=slave, info=info)


def _needle_section(tip: Tip, R: float, H: float, depth: float, edge_radius: float
                    ) -> tuple[FloatArray, FloatArray, float]:
    """The tip's wall profile (r, z), the needle's section in the model frame
    (X = r, Y = z_max − z; its front's corners rounded to ``edge_radius``)
    and the checked edge radius (mm)."""
    prof = wall_profile(tip)
    r_max = float(prof[:, 0].max())
    if r_max >= 0.5 * R:
        raise SpecError(f"the needle's outer radius {r_max:.6g} mm does not fit the block "
                        f"radius {R:g} mm; allowed up to half of it")
    z_max = float(prof[:, 1].max())
    d_needle = min(max(FINE_DEPTH, depth), 0.8 * H)
    margin = max(1.0, 0.5 * d_needle)
    sec = clip_profile(prof, z_max - d_needle - margin)
    needle = np.column_stack([sec[:, 0], z_max - sec[:, 1]])[::-1]
    r_e = v.real("edge_radius", edge_radius, lo=0.0, hi=0.2, unit="mm")
    if r_e > 0:
        front_ids = np.flatnonzero(needle[:, 1] <= tol.fem.profile + r_e)
        needle = round_corners(needle, front_ids, r_e)
        needle[:, 1] -= needle[:, 1].min()
    return prof, needle, r_e


@dataclass(frozen=True)
class _Zones:
    """The mesh zones (mm): the fine box (r₀, r₁, y₀, y₁) at h, the nose box
    and its size, the far size, the grading width, the edge's radii."""

    box: tuple[float, float, float, float]
    nose: tuple[float, float, float, float]
    h_nose: float
    h_far: float
    grade: float
    d_fine: float
    r_lo: float
    r_hi: float


def _zones(needle: FloatArray, *, R: float, H: float, depth: float, h: float,
           far: float | None, nose_refine: float, fine_depth: float | None) -> _Zones:
    """The mesh zones around the needle's front; the model's size checked."""
    d_fine = max(FINE_DEPTH, depth) if fine_depth is None else v.real(
        "fine_depth", fine_depth, lo=0.0, unit="mm")
    d_fine = min(d_fine, 0.8 * H)
    # the edge: the section's points within h of the most advanced height
    front = needle[needle[:, 1] <= h]
    r_lo, r_hi = float(front[:, 0].min()), float(front[:, 0].max())
    r_out = float(needle[:, 0].max())
    pad = max(4 * h, 0.1)
    box = (max(0.0, r_lo - pad), min(R, r_out + pad), -min(H, d_fine + pad), 0.0 + h)
    band = box[1] - box[0]
    grade = min(2.0, 0.5 * R)
    h_far = min(0.5, max(10 * h, 0.25)) if far is None else v.real("far", far, lo=h, hi=R,
                                                                   unit="mm")
    n_est = _estimate_elements(h, band, grade, h_far, d_fine, R, H)
    if n_est > MAX_ELEMENTS:
        raise SpecError(f"mesh = {h * UM_PER_MM:g} µm, meshed fine to {d_fine:g} mm, needs "
                        f"about {n_est:.0f} elements; allowed up to {MAX_ELEMENTS} "
                        "(a coarser --mesh-um, or a shallower --fine-depth-mm)")
    # the tissue that wraps the needle's front: finer still (h / nose_refine)
    h_nose = h / nose_refine
    nose = (r_lo - 2 * h, r_hi + 2 * h, -3 * h, h_nose)
    return _Zones(box, nose, h_nose, h_far, grade, d_fine, r_lo, r_hi)


def _increments(h: float, depth: float, max_increment: float | None) -> tuple[float, float]:
    """The first and the largest needle advance per increment (mm): the
    largest min(:data:`MAX_STEP`, 2h) unless given, the first min(that,
    h / 10), neither beyond ``depth``."""
    dmax = min(MAX_STEP, 2 * h, depth) if max_increment is None else v.real(
        "max_increment", max_increment, lo=0.0, lo_open=True, unit="mm")
    dmax = min(dmax, depth)
    return min(dmax, 0.1 * h), dmax


def _stick_ratio(slave: str, stick_ratio: float | None, cut: str) -> float:
    """The checked stick slope ratio (default :data:`STICK_RATIO`, 1 for the
    erosion cut); ``slave`` checked too."""
    if slave not in SLAVES:
        raise SpecError(f"slave = {slave!r} is not valid; expected one of: " + ", ".join(SLAVES))
    ratio = (1.0 if cut == "erosion" else STICK_RATIO) if stick_ratio is None else stick_ratio
    return v.real("stick_ratio", ratio, lo=0.0, hi=1.0, lo_open=True)


def auto_slave(needle: ArrayLike, h: float) -> str:
    """``slave="auto"`` resolved: ``tissue`` when the needle's front (the
    section's points within ``h`` of its most advanced point; model frame,
    mm) is at least :data:`SLAVE_TISSUE_ELEMENTS` elements of size ``h``
    (mm) wide, else ``needle``."""
    sec = np.asarray(needle, dtype=float)
    front = sec[sec[:, 1] <= sec[:, 1].min() + h, 0]
    return "tissue" if np.ptp(front) >= SLAVE_TISSUE_ELEMENTS * h else "needle"


def _slave(slave: str, erosion: bool, needle: FloatArray, h: float) -> str:
    """Whose nodes are the contact's slaves: the tissue's for the erosion cut,
    :func:`auto_slave` for ``auto``, else as asked."""
    if erosion:
        return "tissue"
    return auto_slave(needle, h) if slave == "auto" else slave


def _crush_info(column: tuple[float, float, float, int, int], aspect: float,
                grading: float) -> dict[str, Any]:
    """The pre-distorted column for the model's ``info``: its aspect, radii
    and depth (mm), layers and the layers' growth ratio."""
    return {"crush_aspect": round(float(aspect), 9),
            "crush_column_mm": [round(column[0], 9), round(column[1], 9), round(-column[2], 9)],
            "crush_layers": column[4], "crush_growth": round(grading, 9)}


def _crush_column(z: _Zones, *, h: float, H: float, aspect: float, depth: float
                  ) -> tuple[tuple[float, float, float, int, int] | None, float]:
    """The pre-distorted column under the needle's front (r_a, r_b, y_bottom,
    elements across, layers) and its layers' growth ratio toward the top, or
    (None, 1) for ``aspect`` 1: elements h wide whose height grows
    geometrically from h at ``depth`` below the top to ``aspect`` × h at it,
    so that the tissue the front crushes (a principal stretch of about
    1 / aspect along the axis) is near square when crushed."""
    a = v.real("crush_aspect", aspect, lo=1.0, hi=8.0)
    if a <= 1.0:
        return None, 1.0
    L = v.real("crush_depth", depth, lo=a * h, hi=0.5 * H, unit="mm")
    r_a, r_b = max(z.r_lo - h, 0.0), z.r_hi + h
    n_r = max(2, int(np.ceil((r_b - r_a) / h - tol.fem.ceil_slack)))
    n_y = 1
    while True:  # the fewest layers whose heights, h up to a h, reach L
        q = a ** (1.0 / max(n_y - 1, 1)) if n_y > 1 else 1.0
        heights = h * q ** np.arange(n_y) if n_y > 1 else np.array([a * h])
        if heights.sum() >= L - tol.fem.ceil_slack * h:
            break
        n_y += 1
    return (r_a, r_b, -L, n_r, n_y), q


def _erosion_column(needle: FloatArray, *, H: float, depth: float, h: float, r_e: float,
                    cut_step: float | None, cut_lead: int
                    ) -> tuple[tuple[float, float, float, int, int], float, int]:
    """The erosion's cut column (r_a, r_b, y_bottom, elements across, layers),
    its layer thickness (mm) and lead (layers)."""
    dz = h if cut_step is None else v.real("cut_step", cut_step, lo=MIN_ELEMENT_MM, hi=depth,
                                           unit="mm")
    lead = int(v.real("cut_lead", cut_lead, lo=0, hi=3))
    tip_pts = needle[needle[:, 1] <= r_e + tol.fem.profile]
    r_a, r_b = float(tip_pts[:, 0].min()), float(tip_pts[:, 0].max())
    n_y = int(np.ceil(depth / dz - tol.fem.ceil_slack)) + 2
    if n_y * dz >= 0.9 * H:
        raise SpecError(f"the cut path to depth {n_y * dz:g} mm does not fit the block "
                        f"height {H:g} mm")
    n_x = max(2, int(np.ceil((r_b - r_a) / h - tol.fem.ceil_slack)))
    return (r_a, r_b, -n_y * dz, n_x, n_y), dz, lead


def _contact_surfaces(nodes: FloatArray, tb: list[ElementBlock], nb: list[ElementBlock],
                      y_cut: float, eps: float) -> dict[str, list[tuple[int, int]]]:
    """TISSUE: the block's top faces; NEEDLE: the needle's faces below its cut
    at Y = ``y_cut``."""
    top = [(e, f) for e, f, ns in boundary_faces(tb)
           if np.all(np.abs(nodes[np.asarray(ns) - 1, 1]) <= eps)]
    master = [(e, f) for e, f, ns in boundary_faces(nb)
              if np.any(nodes[np.asarray(ns) - 1, 1] < y_cut - eps)]
    return {"TISSUE": top, "NEEDLE": master}


_Column = tuple[float, float, float, int, int]
_Face = tuple[int, int, list[int]]


def _column_faces(nodes: FloatArray, tb: list[ElementBlock], column: _Column, dz: float,
                  eps: float) -> tuple[dict[int, int], list[_Face], dict[int, int],
                                       set[tuple[int, int]]]:
    """The cut column's elements with their layer (0 at the top), every
    tissue face (element, face, node ids), the face on top of each column
    element and the faces of the column's walls."""
    r_a, r_b, y_b = column[:3]
    layer_of: dict[int, int] = {}
    faces: list[_Face] = []
    for b in tb:
        for f, loc in enumerate(FACE_NODES[b.etype], 1):
            for e, row in zip(b.ids.tolist(), b.conn[:, loc].tolist()):
                faces.append((e, f, row))
        c = nodes[b.conn - 1].mean(axis=1)
        inside = (c[:, 0] > r_a) & (c[:, 0] < r_b) & (c[:, 1] > y_b)
        layer_of.update(zip(b.ids[inside].tolist(),
                            np.floor(-c[inside, 1] / dz).astype(int).tolist()))
    near = eps * 10
    top_of, walls = {}, set()
    for e, f, ns in faces:
        p = nodes[np.asarray(ns) - 1]
        if e in layer_of:
            if np.all(np.abs(p[:, 1] + layer_of[e] * dz) <= near):
                top_of[e] = f
        elif (np.all(np.abs(p[:, 0] - r_a) <= near) or np.all(np.abs(p[:, 0] - r_b) <= near)) \
                and np.all(p[:, 1] >= y_b - eps):
            walls.add((e, f))
    return layer_of, faces, top_of, walls


def _erosion_stages(nodes: FloatArray, tb: list[ElementBlock], column: _Column, dz: float,
                    lead: int, depth: float, out: tuple[float, ...],
                    surfaces: dict[str, list[tuple[int, int]]], eps: float
                    ) -> tuple[tuple[tuple[float, IntArray, str], ...], dict[str, IntArray]]:
    """The steps of the erosion model (see :class:`~tipgeo.fem.model.FemModel`
    ``stages``) and its node surfaces: ``TISSUE`` (the block's top outside
    the cut column and the column's walls, which are never removed; it takes
    the place of the element surface ``TISSUE`` in ``surfaces``) and
    ``EXPOSED<n>``, the inner nodes of the top of layer n (0 at the top),
    the contact of the steps after n layers are gone."""
    layer_of, faces, top_of, walls = _column_faces(nodes, tb, column, dz, eps)
    cid = list(layer_of)
    # every contact of the erosion model has the tissue's nodes slave to the
    # needle's faces: the block's top and the cut's walls (never removed),
    # and each step the nodes of the layer top it exposes
    keep = {(e, f) for e, f in surfaces.pop("TISSUE") if e not in layer_of} | walls
    kept = [ns for e, f, ns in faces if (e, f) in keep]
    wall_nodes = np.unique(np.asarray(kept, dtype=int))
    node_surfaces = {"TISSUE": wall_nodes}
    slack = tol.fem.ceil_slack
    ends = sorted({round(min(k * dz, depth), 12) for k in range(1, int(np.ceil(
        depth / dz - slack)) + 1)} | {round(d, 12) for d in out})
    stages, gone, prev = [], 0, 0.0
    for d in ends:
        n_gone = max(gone, int(np.ceil((prev + lead * dz) / dz - slack)))
        removed = np.array(sorted(e for e in cid if gone <= layer_of[e] < n_gone), dtype=int)
        name = f"EXPOSED{n_gone}"
        if name not in node_surfaces:
            exposed = [ns for e, f, ns in faces if top_of.get(e) == f and layer_of[e] == n_gone]
            node_surfaces[name] = np.setdiff1d(np.unique(np.asarray(exposed, dtype=int)),
                                               wall_nodes)
        stages.append((d, removed, name))
        gone, prev = n_gone, d
    return tuple(stages), node_surfaces
