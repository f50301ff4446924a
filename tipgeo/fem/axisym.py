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

import numpy as np

from .. import validate as v
from ..errors import SpecError
from ..tip import Tip
from ..tolerances import tol
from .material import DEFAULT_NU, fem_material, friction_coefficient
from .mesh import mesh_2d
from .model import FACE_NODES, ElementBlock, FemModel, boundary_faces
from .profile import clip_profile, round_corners, wall_profile

__all__ = ["axisymmetric_model", "BLOCK_2D", "AXISYMMETRIC_FORCE_SCALE", "CUTS"]

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

#: Limits on the model size, checked before meshing (elements).
MAX_ELEMENTS = 400_000


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
                       fine_depth: float | None = None) -> FemModel:
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
    contact : ``node`` (node-to-surface, the needle's nodes slave to the
        tissue's faces, so that the narrow front cannot slip between tissue
        nodes) | ``surface`` (surface-to-surface)
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
    h = v.real("mesh", mesh, lo=0.001, hi=0.5, unit="mm")
    prof = wall_profile(tip)
    r_max = float(prof[:, 0].max())
    if r_max >= 0.5 * R:
        raise SpecError(f"the needle's outer radius {r_max:.6g} mm does not fit the block "
                        f"radius {R:g} mm; allowed up to half of it")
    z_max = float(prof[:, 1].max())
    d_fine = max(FINE_DEPTH, depth) if fine_depth is None else v.real(
        "fine_depth", fine_depth, lo=0.0, unit="mm")
    d_fine = min(d_fine, 0.8 * H)
    d_needle = min(max(FINE_DEPTH, depth), 0.8 * H)
    margin = max(1.0, 0.5 * d_needle)
    sec = clip_profile(prof, z_max - d_needle - margin)
    needle = np.column_stack([sec[:, 0], z_max - sec[:, 1]])[::-1]
    r_e = v.real("edge_radius", edge_radius, lo=0.0, hi=0.2, unit="mm")
    if r_e > 0:
        front_ids = np.flatnonzero(needle[:, 1] <= tol.fem.profile + r_e)
        needle = round_corners(needle, front_ids, r_e)
        needle[:, 1] -= needle[:, 1].min()
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
        raise SpecError(f"mesh = {h * 1e3:g} µm, meshed fine to {d_fine:g} mm, needs about "
                        f"{n_est:.0f} elements; allowed up to {MAX_ELEMENTS} "
                        "(a coarser --mesh-um, or a shallower fine_depth in the API)")
    # the tissue that wraps the needle's front: finer still (h / nose_refine)
    h_nose = h / nose_refine
    nose = (r_lo - 2 * h, r_hi + 2 * h, -3 * h, h_nose)
    if cut not in CUTS:
        raise SpecError(f"cut = {cut!r} is not valid; expected one of: " + ", ".join(CUTS))
    column = None
    if cut == "erosion":
        dz = h if cut_step is None else v.real("cut_step", cut_step, lo=0.001, hi=depth,
                                               unit="mm")
        lead = int(v.real("cut_lead", cut_lead, lo=0, hi=3))
        tip_pts = needle[needle[:, 1] <= r_e + tol.fem.profile]
        r_a, r_b = float(tip_pts[:, 0].min()), float(tip_pts[:, 0].max())
        n_y = int(np.ceil(depth / dz - 1e-9)) + 2
        if n_y * dz >= 0.9 * H:
            raise SpecError(f"the cut path to depth {n_y * dz:g} mm does not fit the block "
                            f"height {H:g} mm")
        column = (r_a, r_b, -n_y * dz, max(2, int(np.ceil((r_b - r_a) / h - 1e-9))), n_y)
    nodes, parts = mesh_2d(needle, block=(R, H), boxes=[(box, h), (nose, h_nose)],
                           h_far=h_far, grade=grade, column=column)
    blocks, eid = [], 1
    for part in ("tissue", "needle"):
        for et, conn in sorted(parts[part].items()):
            blocks.append(ElementBlock(et, part, np.arange(eid, eid + len(conn)), conn))
            eid += len(conn)
    eps = 1e-9 * R
    tb = [b for b in blocks if b.part == "tissue"]
    nb = [b for b in blocks if b.part == "needle"]
    top = [(e, f) for e, f, ns in boundary_faces(tb)
           if np.all(np.abs(nodes[np.asarray(ns) - 1, 1]) <= eps)]
    y_cut = float(needle[:, 1].max())
    master = [(e, f) for e, f, ns in boundary_faces(nb)
              if np.any(nodes[np.asarray(ns) - 1, 1] < y_cut - eps)]
    tissue_nodes = np.unique(np.concatenate([b.conn.ravel() for b in tb]))
    tn = nodes[tissue_nodes - 1]
    nsets = {"BASE": tissue_nodes[np.abs(tn[:, 1] + H) <= eps],
             "AXIS": tissue_nodes[np.abs(tn[:, 0]) <= eps],
             "NEEDLE": np.unique(np.concatenate([b.conn.ravel() for b in nb]))}
    mat = fem_material(tissue, material_model, nu)
    if friction is None:
        mu, mu_src = friction_coefficient(tissue, 0.0)
    else:
        mu, mu_src = v.real("friction", friction, lo=0.0, hi=2.0), "given"
    dmax = min(MAX_STEP, 2 * h, depth) if max_increment is None else v.real(
        "max_increment", max_increment, lo=0.0, lo_open=True, unit="mm")
    dmax = min(dmax, depth)
    d0 = min(dmax, 0.1 * h)
    out = tuple(v.real("output depth", d, lo=0.0, hi=depth, lo_open=True, unit="mm")
                for d in output_depths)
    info = {"element_size_um": round(h * 1e3, 6), "element_size_far_um": round(h_far * 1e3, 6),
            "element_size_front_um": round(h_nose * 1e3, 6),
            "fine_zone_mm": [round(x, 6) for x in box], "nodes": len(nodes),
            "tissue_elements": int(sum(len(b.ids) for b in tb)),
            "needle_elements": int(sum(len(b.ids) for b in nb)),
            "block_mm": [R, H], "edge_r_mm": [r_lo, r_hi], "tip": tip.spec.name if tip.spec
            else "imported", "tissue": mat.name, "material": mat.model,
            "material_source": mat.source, "edge_radius_um": round(r_e * 1e3, 6),
            "inner_diameter_mm": 2 * float(prof[:, 0].min()),
            "_needle_section": needle.tolist(), "contact": contact, "nu": nu, "friction": mu,
            "friction_source": mu_src, "fine_depth_mm": round(d_fine, 9),
            "first_increment_mm": round(d0, 9), "max_increment_mm": round(dmax, 9)}
    surfaces, stages, node_surfaces = {"TISSUE": top, "NEEDLE": master}, (), {}
    if column is not None:
        stages, node_surfaces = _erosion_stages(nodes, tb, column, dz, lead, depth, out,
                                                surfaces, eps)
        info.update({"cut": cut, "cut_step_um": round(dz * 1e3, 6), "cut_lead": lead,
                     "cut_r_mm": [column[0], column[1]], "steps": len(stages)})
    return FemModel(kind="axisymmetric", name=info["tip"], nodes=nodes, blocks=blocks,
                    nsets=nsets, fixed={"BASE": (1, 2), "AXIS": (1,)}, stages=stages,
                    node_surfaces=node_surfaces,
                    surfaces=surfaces, material=mat, friction=mu,
                    depth=depth, penalty=penalty_factor * mat.E0 / h if contact_stiffness is None
                    else v.real("contact_stiffness", contact_stiffness, lo=0.0, lo_open=True,
                                unit="MPa/mm"),
                    force_scale=AXISYMMETRIC_FORCE_SCALE,
                    # a 1 nm floor on the smallest increment
                    increments=(d0 / depth, 1e-6 * min(1.0, 1.0 / depth), dmax / depth),
                    output_depths=out, contact=contact,
                    slave="tissue" if stages else "needle", info=info)



def _erosion_stages(nodes, tb, column, dz, lead, depth, out, surfaces, eps):
    """The steps of the erosion model (see :class:`~tipgeo.fem.model.FemModel`
    ``stages``) and its node surfaces: ``TISSUE`` (the block's top outside
    the cut column and the column's walls, which are never removed; it takes
    the place of the element surface ``TISSUE`` in ``surfaces``) and
    ``EXPOSED<n>``, the inner nodes of the top of layer n (0 at the top),
    the contact of the steps after n layers are gone."""
    r_a, r_b, y_b = column[:3]
    cid, layer = [], []
    faces = []  # (element, face, node ids) of every tissue element
    for b in tb:
        for f, loc in enumerate(FACE_NODES[b.etype], 1):
            for e, row in zip(b.ids.tolist(), b.conn[:, loc].tolist()):
                faces.append((e, f, row))
        c = nodes[b.conn - 1].mean(axis=1)
        inside = (c[:, 0] > r_a) & (c[:, 0] < r_b) & (c[:, 1] > y_b)
        cid += b.ids[inside].tolist()
        layer += np.floor(-c[inside, 1] / dz).astype(int).tolist()
    col = set(cid)
    layer_of = dict(zip(cid, layer))
    xy = nodes
    top_of, walls = {}, []
    for e, f, ns in faces:
        p = xy[np.asarray(ns) - 1]
        if e in col:
            y_top = -layer_of[e] * dz
            if np.all(np.abs(p[:, 1] - y_top) <= eps * 10):
                top_of[e] = f
        elif np.all(np.abs(p[:, 0] - r_a) <= eps * 10) or np.all(np.abs(p[:, 0] - r_b)
                                                                 <= eps * 10):
            if np.all(p[:, 1] >= y_b - eps):
                walls.append((e, f, float(p[:, 1].min())))
    # every contact of the erosion model has the tissue's nodes slave to the
    # needle's faces: the block's top and the cut's walls (never removed),
    # and each step the nodes of the layer top it exposes
    keep = {(e, f) for e, f in surfaces.pop("TISSUE") if e not in col} | {
        (e, f) for e, f, _ in walls}
    kept = [ns for e, f, ns in faces if (e, f) in keep]
    wall_nodes = np.unique(np.asarray(kept, dtype=int))
    node_surfaces = {"TISSUE": wall_nodes}
    ends = sorted({round(min(k * dz, depth), 12) for k in range(1, int(np.ceil(
        depth / dz - 1e-9)) + 1)} | {round(d, 12) for d in out})
    stages, gone, prev = [], 0, 0.0
    for d in ends:
        n_gone = max(gone, int(np.ceil((prev + lead * dz) / dz - 1e-9)))
        removed = np.array(sorted(e for e in cid if gone <= layer_of[e] < n_gone), dtype=int)
        name = f"EXPOSED{n_gone}"
        if name not in node_surfaces:
            exposed = [ns for e, f, ns in faces if e in top_of and top_of[e] == f
                       and layer_of[e] == n_gone]
            node_surfaces[name] = np.setdiff1d(np.unique(np.asarray(exposed, dtype=int)),
                                               wall_nodes)
        stages.append((d, removed, name))
        gone, prev = n_gone, d
    return tuple(stages), node_surfaces
