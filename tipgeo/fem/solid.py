"""The 3D indentation model (thesis §4.4.1.1, §5.4, Appendix B1/B4) of any
tip, reduced by the mirror symmetries the tip has.

Frame and units: the model frame of :mod:`tipgeo.fem.model`, mm. The cannula
frame maps to it by X = x, Y = z_max − z, Z = y (right-handed; the needle
moves along −Y, the block's top face is Y = 0). A tip symmetric under
x → −x keeps X ≥ 0 (plane X = 0 held normal to itself), under y → −y keeps
Z ≥ 0; both for an axisymmetric tip (a quarter, as the thesis's Fig. 4.8), one
for a bevel (a half), none for a helix. ``force_scale`` restores the whole
needle (4, 2 or 1).

The block is a cylinder of radius R and height H (thesis: 10 × 7.5 mm),
base fixed, other faces free. Its top face is meshed with quadrilaterals,
graded toward the needle's footprint, and extruded down in layers (h thick
to below the final depth, then growing) into hexahedra and wedges (C3D8I,
C3D6). The needle is its front part (from the most advanced point back to
the depth plus a margin), tetrahedralised (C3D4) and held rigid by prescribed
displacements.
"""

from __future__ import annotations

import numpy as np

from .. import validate as v
from ..errors import FemError, SpecError
from ..tip import Tip
from ..tolerances import MAX_FEM_ELEMENTS_3D, MAX_NEEDLE_FACES_3D
from .material import DEFAULT_NU, fem_material, friction_coefficient
from .mesh import gmsh_session
from .model import ElementBlock, FemModel, boundary_faces

__all__ = ["indentation_model", "mirror_planes", "BLOCK_3D"]

#: Block radius and height of the thesis's 3D model (§4.4.1.1), mm.
BLOCK_3D = (10.0, 7.5)

#: Limit on the model size, checked before meshing (elements).
MAX_ELEMENTS_3D = MAX_FEM_ELEMENTS_3D

_GMSH_3D = {4: ("C3D4", 4), 5: ("C3D8", 8), 6: ("C3D6", 6)}


def _gmsh_msg(e: BaseException) -> str:
    """The first line of a gmsh error (gmsh raises a bare Exception)."""
    text = str(e).strip()
    return text.splitlines()[0][:200] if text else type(e).__name__


def mirror_planes(tip: Tip, tolerance: float = 1e-6) -> tuple[bool, bool]:
    """Whether the tip's mesh maps onto itself under x → −x and under
    y → −y (every mirrored vertex within ``tolerance`` mm of a vertex)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(tip.vertices)
    out = []
    for axis in (0, 1):
        m = tip.vertices.copy()
        m[:, axis] *= -1
        d, _ = tree.query(m)
        out.append(bool(np.max(d) <= tolerance))
    return out[0], out[1]


def _clip_front(tip: Tip, z_cut: float) -> tuple[np.ndarray, np.ndarray]:
    """The tip's solid above z = z_cut as a closed triangle mesh (vertices
    (n, 3), faces (m, 3)), cannula frame, mm."""
    import manifold3d as m3d

    mesh = m3d.Mesh(vert_properties=np.asarray(tip.vertices, dtype=np.float32),
                    tri_verts=np.asarray(tip.faces, dtype=np.uint32))
    solid = m3d.Manifold(mesh)
    lo = tip.vertices.min(axis=0) - 1.0
    hi = tip.vertices.max(axis=0) + 1.0
    box = m3d.Manifold.cube([hi[0] - lo[0], hi[1] - lo[1], hi[2] - z_cut]).translate(
        [lo[0], lo[1], z_cut])
    front = solid ^ box
    out = front.to_mesh()
    v_ = np.asarray(out.vert_properties, dtype=float)[:, :3]
    f_ = np.asarray(out.tri_verts, dtype=np.int64)
    if len(f_) == 0:
        raise FemError("the needle's front is empty after clipping")
    return v_, f_


def _needle_tets(gmsh, verts: np.ndarray, faces: np.ndarray, h: float) -> None:
    """Add the closed surface (model frame) as a discrete volume and mesh it
    with tetrahedra (the surface mesh kept)."""
    s = gmsh.model.addDiscreteEntity(2)
    tags = np.arange(1, len(verts) + 1)
    gmsh.model.mesh.addNodes(2, s, tags.tolist(), verts.ravel().tolist())
    gmsh.model.mesh.addElementsByType(s, 2, [], (faces + 1).ravel().tolist())
    loop = gmsh.model.geo.addSurfaceLoop([s])
    gmsh.model.geo.addVolume([loop])
    gmsh.model.geo.synchronize()


def indentation_model(tip: Tip, *, depth: float, tissue: str = "pvc-sp0",
                      material_model: str = "arruda-boyce", nu: float = DEFAULT_NU,
                      friction: float | None = None, mesh: float = 0.1,
                      block: tuple[float, float] = BLOCK_3D,
                      output_depths: tuple[float, ...] = (),
                      max_increment: float | None = None, penalty_factor: float = 5.0,
                      far: float = 1.0, contact: str = "node",
                      contact_stiffness: float | None = None,
                      hexahedron: str = "C3D8I") -> FemModel:
    """The 3D indentation model of ``tip`` pushed ``depth`` into a block.

    Parameters
    ----------
    tip : Tip — any tip
    depth : float — needle travel, mm
    tissue, material_model, nu, friction, penalty_factor, contact,
    contact_stiffness : as
        :func:`tipgeo.fem.axisym.axisymmetric_model`
    mesh : float — element size h at the footprint, mm
    block : (R, H) — block radius and height, mm
    far : float — element size far from the footprint, mm
    hexahedron : ``C3D8I`` (incompatible modes: less volumetric and shear
        locking of the nearly incompressible tissue) | ``C3D8``
    """
    R, H = (v.length("block radius", block[0]), v.length("block height", block[1]))
    depth = v.real("depth", depth, lo=0.0, hi=0.8 * H, lo_open=True, unit="mm")
    h = v.real("mesh", mesh, lo=0.005, hi=1.0, unit="mm")
    far = v.real("far", far, lo=h, hi=R, unit="mm")
    if hexahedron not in ("C3D8I", "C3D8"):
        raise SpecError(f"hexahedron = {hexahedron!r} is not valid; expected one of: C3D8I, "
                        "C3D8")
    sx, sy = mirror_planes(tip)
    z_max = float(tip.vertices[:, 2].max())
    rho = np.hypot(tip.vertices[:, 0], tip.vertices[:, 1])
    r_in, r_out = float(rho.min()), float(rho.max())
    if r_out >= 0.5 * R:
        raise SpecError(f"the needle's outer radius {r_out:.6g} mm does not fit the block "
                        f"radius {R:g} mm; allowed up to half of it")
    margin = max(0.3, 3 * h)
    # layers: h down to below the depth, then growing by 1.5 to `far`
    t, layers = 0.0, []
    while t < H - 1e-12:
        dz = h if t < depth + margin else min(far, 1.5 * layers[-1])
        dz = min(dz, H - t)
        layers.append(dz)
        t += dz
    ring = 2 * np.pi * 0.5 * (r_in + r_out) * (0.25 if sx and sy else 0.5 if sx or sy else 1)
    n_est = (ring * (r_out - r_in + 2 * margin) / h ** 2 + np.pi * R ** 2 / far ** 2) * len(
        layers)
    # the needle's tetrahedra: its front's volume at size h (≈ 6 per h³)
    frac = 0.25 if sx and sy else 0.5 if sx or sy else 1.0
    n_est += 6.0 * frac * np.pi * (r_out ** 2 - r_in ** 2) * (depth + margin) / h ** 3
    if n_est > MAX_ELEMENTS_3D:
        raise SpecError(f"mesh = {h * 1e3:g} µm needs about {n_est:.0f} elements; allowed up "
                        f"to {MAX_ELEMENTS_3D} (a coarser --mesh-um, a shallower --depth-mm)")
    fv, ff = _clip_front(tip, z_max - depth - margin)
    if len(ff) > MAX_NEEDLE_FACES_3D:  # before gmsh: its tetrahedra cost grows steeply
        raise SpecError(f"depth = {depth:g} mm: the needle's front has {len(ff)} surface "
                        f"triangles; the 3D model meshes at most {MAX_NEEDLE_FACES_3D} (a "
                        "shallower --depth-mm, a coarser tolerance, or the axisymmetric model "
                        "for a round tip)")
    nv = np.column_stack([fv[:, 0], z_max - fv[:, 2], fv[:, 1]])
    X0, Z0 = (0.0 if sx else -R), (0.0 if sy else -R)
    with gmsh_session() as gmsh:
        occ = gmsh.model.occ
        disk = occ.addDisk(0, 0, 0, R, R)
        keep = occ.addRectangle(X0, Z0, 0, R - X0, R - Z0)
        top, _ = occ.intersect([(2, disk)], [(2, keep)])
        occ.synchronize()
        f = gmsh.model.mesh.field
        c1 = occ.addCircle(0, 0, 0, r_in)
        c2 = occ.addCircle(0, 0, 0, r_out)
        occ.synchronize()
        d = f.add("Distance")
        f.setNumbers(d, "CurvesList", [c1, c2])
        f.setNumber(d, "Sampling", 400)
        th = f.add("Threshold")
        f.setNumber(th, "InField", d)
        f.setNumber(th, "SizeMin", h)
        f.setNumber(th, "SizeMax", far)
        f.setNumber(th, "DistMin", margin)
        f.setNumber(th, "DistMax", margin + 4 * far)
        bx = f.add("Box")
        f.setNumber(bx, "VIn", h)
        f.setNumber(bx, "VOut", far)
        f.setNumber(bx, "XMin", -r_in)
        f.setNumber(bx, "XMax", r_in)
        f.setNumber(bx, "YMin", -r_in)
        f.setNumber(bx, "YMax", r_in)
        f.setNumber(bx, "ZMin", -1)
        f.setNumber(bx, "ZMax", 1)
        mn = f.add("Min")
        f.setNumbers(mn, "FieldsList", [th])
        f.setAsBackgroundMesh(mn)
        for k in ("Mesh.MeshSizeExtendFromBoundary", "Mesh.MeshSizeFromPoints",
                  "Mesh.MeshSizeFromCurvature"):
            gmsh.option.setNumber(k, 0)
        occ.remove([(1, c1), (1, c2)])
        occ.synchronize()
        gmsh.option.setNumber("Mesh.Algorithm", 8)
        gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)
        gmsh.option.setNumber("Mesh.RecombineAll", 1)
        # the top face lies in the x-y plane of gmsh here; extrude along −z, map
        # (x, y, z) of gmsh to model (X, Z, Y) afterwards
        heights = np.cumsum(layers) / H
        occ.extrude(top, 0, 0, -H, numElements=[1] * len(layers), heights=heights.tolist(),
                    recombine=True)
        occ.synchronize()
        try:
            gmsh.model.mesh.generate(3)
        except Exception as e:  # gmsh raises a bare Exception with its last error
            raise FemError(f"gmsh could not mesh the block ({_gmsh_msg(e)}); try another "
                           "--mesh-um") from None
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        tags = np.asarray(tags, dtype=np.int64)
        xyz = np.asarray(xyz).reshape(-1, 3)
        tissue_conn = {}
        for et, _, nodes in zip(*gmsh.model.mesh.getElements(3)):
            name, k = _GMSH_3D.get(int(et), (None, 0))
            if name is None:
                raise FemError(f"gmsh made 3D elements of type {et}; expected hexahedra, "
                               "prisms or tetrahedra")
            if name == "C3D8":
                name = hexahedron
            tissue_conn[name] = np.asarray(nodes, dtype=np.int64).reshape(-1, k)
    tissue_xyz = np.column_stack([xyz[:, 0], xyz[:, 2], xyz[:, 1]])
    # needle: tetrahedralise the clipped front in a second session
    with gmsh_session() as gmsh:
        _needle_tets(gmsh, nv, ff, h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", max(h, 0.5 * (r_out - r_in)))
        try:
            gmsh.model.mesh.generate(3)
        except Exception as e:  # gmsh raises a bare Exception with its last error
            raise FemError(f"gmsh could not tetrahedralise the needle's front to depth "
                           f"{depth:g} mm ({_gmsh_msg(e)}); try another --depth-mm or "
                           "--mesh-um") from None
        ntags, nxyz, _ = gmsh.model.mesh.getNodes()
        ntags = np.asarray(ntags, dtype=np.int64)
        nxyz = np.asarray(nxyz).reshape(-1, 3)
        needle_conn = {}
        for et, _, nodes in zip(*gmsh.model.mesh.getElements(3)):
            if int(et) != 4:
                raise FemError(f"gmsh made needle elements of type {et}; expected tetrahedra")
            needle_conn["C3D4"] = np.asarray(nodes, dtype=np.int64).reshape(-1, 4)
    if not needle_conn:
        raise FemError("gmsh could not tetrahedralise the needle's front")
    # the needle's reduced part, by whole elements (centroids on the kept side)
    def keep_rule(P):
        ok = np.ones(len(P), dtype=bool)
        if sx:
            ok &= P[..., 0].mean(axis=1) >= 0
        if sy:
            ok &= P[..., 2].mean(axis=1) >= 0
        return ok

    nodes, blocks, eid = [], [], 1

    def add(part, conn_by_type, tg, xyz_):
        nonlocal eid
        pos = np.full(int(tg.max()) + 1, -1, dtype=np.int64)
        pos[tg] = np.arange(len(tg))
        base = sum(len(n) for n in nodes)
        used = np.unique(np.concatenate([c.ravel() for c in conn_by_type.values()]))
        new = np.zeros(int(tg.max()) + 1, dtype=np.int64)
        new[used] = np.arange(base + 1, base + len(used) + 1)
        nodes.append(xyz_[pos[used]])
        for et, c in sorted(conn_by_type.items()):
            blocks.append(ElementBlock(et, part, np.arange(eid, eid + len(c)), new[c]))
            eid += len(c)

    add("tissue", tissue_conn, tags, tissue_xyz)
    P = nxyz[np.searchsorted(ntags, needle_conn["C3D4"])] if np.all(np.diff(ntags) > 0) else None
    if P is None:
        order = np.argsort(ntags)
        P = nxyz[order][np.searchsorted(ntags[order], needle_conn["C3D4"])]
    kept = needle_conn["C3D4"][keep_rule(P)]
    add("needle", {"C3D4": kept}, ntags, nxyz)
    allnodes = np.vstack(nodes)
    _fix_orientation(allnodes, blocks)
    eps = 1e-9 * R
    tb = [b for b in blocks if b.part == "tissue"]
    nb = [b for b in blocks if b.part == "needle"]
    top = [(e, fc) for e, fc, ns in boundary_faces(tb)
           if np.all(np.abs(allnodes[np.asarray(ns) - 1, 1]) <= eps)]
    y_cut = float(allnodes[np.unique(np.concatenate([b.conn.ravel() for b in nb])) - 1, 1].max())
    master = [(e, fc) for e, fc, ns in boundary_faces(nb)
              if np.any(allnodes[np.asarray(ns) - 1, 1] < y_cut - 1e-6)
              and not (sx and np.all(np.abs(allnodes[np.asarray(ns) - 1, 0]) <= 1e-6))
              and not (sy and np.all(np.abs(allnodes[np.asarray(ns) - 1, 2]) <= 1e-6))]
    tn = np.unique(np.concatenate([b.conn.ravel() for b in tb]))
    T = allnodes[tn - 1]
    nsets = {"BASE": tn[np.abs(T[:, 1] + H) <= eps]}
    fixed = {"BASE": (1, 2, 3)}
    if sx:
        nsets["SYMX"] = tn[np.abs(T[:, 0]) <= eps]
        fixed["SYMX"] = (1,)
    if sy:
        nsets["SYMZ"] = tn[np.abs(T[:, 2]) <= eps]
        fixed["SYMZ"] = (3,)
    nsets["NEEDLE"] = np.unique(np.concatenate([b.conn.ravel() for b in nb]))
    mat = fem_material(tissue, material_model, nu)
    if friction is None:
        mu, mu_src = friction_coefficient(tissue, 0.0)
    else:
        mu, mu_src = v.real("friction", friction, lo=0.0, hi=2.0), "given"
    dmax = depth / 10 if max_increment is None else v.real(
        "max_increment", max_increment, lo=0.0, hi=depth, lo_open=True, unit="mm")
    out = tuple(v.real("output depth", dd, lo=0.0, hi=depth, lo_open=True, unit="mm")
                for dd in output_depths)
    sym_tris, sym_axis = None, (2 if sy else 0 if sx else None)
    if sym_axis is not None:  # tissue faces on the symmetry plane, for the contour picture
        sym_tris = []
        for _e, _fc, ns in boundary_faces(tb):
            ns = list(ns)
            if np.all(np.abs(allnodes[np.asarray(ns) - 1, sym_axis]) <= eps):
                sym_tris += [[ns[0], ns[i], ns[i + 1]] for i in range(1, len(ns) - 1)]
    scale = (2.0 if sx else 1.0) * (2.0 if sy else 1.0)
    info = {"element_size_um": round(h * 1e3, 6), "element_size_far_um": round(far * 1e3, 6),
            "layers": len(layers), "nodes": len(allnodes),
            "tissue_elements": int(sum(len(b.ids) for b in tb)),
            "needle_elements": int(sum(len(b.ids) for b in nb)),
            "symmetry": ("x " if sx else "") + ("y" if sy else "") or "none",
            "block_mm": [R, H], "edge_r_mm": [r_in, r_out],
            "tip": tip.spec.name if tip.spec else "imported", "tissue": mat.name,
            "material": mat.model, "material_source": mat.source,
            "inner_diameter_mm": 2 * r_in, "contact": contact, "nu": nu, "friction": mu,
            "friction_source": mu_src, "_symmetry_tris": sym_tris,
            "symmetry_plane": None if sym_axis is None else "XYZ"[sym_axis]}
    return FemModel(kind="3d", name=info["tip"], nodes=allnodes, blocks=blocks, nsets=nsets,
                    fixed=fixed, surfaces={"TISSUE": top, "NEEDLE": master}, material=mat,
                    friction=mu, depth=depth,
                    penalty=penalty_factor * mat.E0 / h if contact_stiffness is None else
                    v.real("contact_stiffness", contact_stiffness, lo=0.0, lo_open=True,
                           unit="MPa/mm"),
                    force_scale=scale, increments=(dmax / depth / 2, 1e-6, dmax / depth),
                    output_depths=out, contact=contact, slave="needle", info=info)


def _signed_volumes(P: np.ndarray, etype: str) -> np.ndarray:
    if etype == "C3D4":
        a, b, c, d = P[:, 0], P[:, 1], P[:, 2], P[:, 3]
    elif etype == "C3D6":
        a, b, c, d = P[:, 0], P[:, 1], P[:, 2], P[:, 3]
    else:
        a, b, c, d = P[:, 0], P[:, 1], P[:, 3], P[:, 4]
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a))


def _fix_orientation(nodes: np.ndarray, blocks: list[ElementBlock]) -> None:
    """Renumber elements with a negative volume (mirror their node order)."""
    flip = {"C3D4": [0, 2, 1, 3], "C3D6": [0, 2, 1, 3, 5, 4],
            "C3D8": [0, 3, 2, 1, 4, 7, 6, 5], "C3D8I": [0, 3, 2, 1, 4, 7, 6, 5]}
    for b in blocks:
        vol = _signed_volumes(nodes[b.conn - 1], b.etype)
        neg = vol < 0
        if np.any(neg):
            b.conn[neg] = b.conn[neg][:, flip[b.etype]]
