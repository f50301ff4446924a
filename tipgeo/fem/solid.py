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

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import validate as v
from ..arrays import FloatArray, IntArray
from ..errors import FemError, SpecError
from ..tip import Tip
from ..tolerances import MAX_FEM_ELEMENTS_3D, MAX_NEEDLE_FACES_3D, tol
from .material import DEFAULT_NU, fem_material, model_friction
from .mesh import gmsh_session
from .model import (
    UM_PER_MM,
    ElementBlock,
    FemModel,
    boundary_faces,
    check_output_depths,
    contact_penalty,
)

__all__ = ["indentation_model", "mirror_planes", "BLOCK_3D"]

#: Block radius and height of the thesis's 3D model (§4.4.1.1), mm.
BLOCK_3D = (10.0, 7.5)

#: Limit on the model size, checked before meshing (elements).
MAX_ELEMENTS_3D = MAX_FEM_ELEMENTS_3D

_GMSH_3D = {4: ("C3D4", 4), 5: ("C3D8", 8), 6: ("C3D6", 6)}

#: Smallest element size at the footprint (mm): 5 µm.
MIN_ELEMENT_MM = 0.005


def _gmsh_msg(e: BaseException) -> str:
    """The first line of a gmsh error (gmsh raises a bare Exception)."""
    text = str(e).strip()
    return text.splitlines()[0][:200] if text else type(e).__name__


def mirror_planes(tip: Tip, tolerance: float | None = None) -> tuple[bool, bool]:
    """Whether the tip's mesh maps onto itself under x → −x and under
    y → −y (every mirrored vertex within ``tolerance`` mm of a vertex;
    default ``tol.fem.mirror``)."""
    from scipy.spatial import cKDTree

    tolerance = tol.fem.mirror if tolerance is None else tolerance
    tree = cKDTree(tip.vertices)
    out = []
    for axis in (0, 1):
        m = tip.vertices.copy()
        m[:, axis] *= -1
        d, _ = tree.query(m)
        out.append(bool(np.max(d) <= tolerance))
    return out[0], out[1]


def _clip_front(tip: Tip, z_cut: float) -> tuple[FloatArray, IntArray]:
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


def _needle_tets(gmsh: Any, verts: FloatArray, faces: IntArray, h: float) -> None:
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
    g = _geometry(tip, depth=depth, mesh=mesh, block=block, far=far, hexahedron=hexahedron)
    _check_size(g)
    fv, ff = _clip_front(tip, g.z_max - g.depth - g.margin)
    if len(ff) > MAX_NEEDLE_FACES_3D:  # before gmsh: its tetrahedra cost grows steeply
        raise SpecError(f"depth = {g.depth:g} mm: the needle's front has {len(ff)} surface "
                        f"triangles; the 3D model meshes at most {MAX_NEEDLE_FACES_3D} (a "
                        "shallower --depth-mm, a coarser tolerance, or the axisymmetric model "
                        "for a round tip)")
    nv = np.column_stack([fv[:, 0], g.z_max - fv[:, 2], fv[:, 1]])
    tags, tissue_xyz, tissue_conn = _mesh_block(g, hexahedron)
    ntags, nxyz, needle_conn = _mesh_needle(g, nv, ff)
    allnodes, blocks = _assemble(g, (tags, tissue_xyz, tissue_conn), (ntags, nxyz, needle_conn))
    eps = tol.fem.plane_rel * g.R
    tb = [b for b in blocks if b.part == "tissue"]
    nb = [b for b in blocks if b.part == "needle"]
    surfaces = _contact_surfaces(g, allnodes, tb, nb, eps)
    nsets, fixed = _node_sets(g, allnodes, tb, nb, eps)
    mat = fem_material(tissue, material_model, nu)
    mu, mu_src = model_friction(tissue, friction)
    dmax = depth / 10 if max_increment is None else v.real(
        "max_increment", max_increment, lo=0.0, hi=g.depth, lo_open=True, unit="mm")
    out = check_output_depths(output_depths, g.depth)
    sym_axis = 2 if g.sy else 0 if g.sx else None
    scale = (2.0 if g.sx else 1.0) * (2.0 if g.sy else 1.0)
    r_in, r_out = g.r_in, g.r_out
    name = tip.spec.name if tip.spec else "imported"
    info = {"element_size_um": round(g.h * UM_PER_MM, 6),
            "element_size_far_um": round(g.far * UM_PER_MM, 6),
            "layers": len(g.layers), "nodes": len(allnodes),
            "tissue_elements": int(sum(len(b.ids) for b in tb)),
            "needle_elements": int(sum(len(b.ids) for b in nb)),
            "symmetry": ("x " if g.sx else "") + ("y" if g.sy else "") or "none",
            "block_mm": [g.R, g.H], "edge_r_mm": [r_in, r_out],
            "tip": name, "tissue": mat.name,
            "material": mat.model, "material_source": mat.source,
            "inner_diameter_mm": 2 * r_in, "contact": contact, "nu": nu, "friction": mu,
            "friction_source": mu_src,
            "_symmetry_tris": _symmetry_tris(allnodes, tb, sym_axis, eps),
            "symmetry_plane": None if sym_axis is None else "XYZ"[sym_axis]}
    return FemModel(kind="3d", name=name, nodes=allnodes, blocks=blocks, nsets=nsets,
                    fixed=fixed, surfaces=surfaces, material=mat,
                    friction=mu, depth=g.depth,
                    penalty=contact_penalty(penalty_factor, mat.E0, g.h, contact_stiffness),
                    force_scale=scale,
                    increments=(dmax / g.depth / 2, tol.fem.min_increment, dmax / g.depth),
                    output_depths=out, contact=contact, slave="needle", info=info)


@dataclass(frozen=True)
class _Geometry:
    """The checked sizes of a 3D model (mm) and the tip's mirror planes."""

    R: float
    H: float
    depth: float
    h: float
    far: float
    sx: bool
    sy: bool
    z_max: float
    r_in: float
    r_out: float
    margin: float
    layers: tuple[float, ...]


def _geometry(tip: Tip, *, depth: float, mesh: float, block: tuple[float, float], far: float,
              hexahedron: str) -> _Geometry:
    """Check the sizes against the block and the tip; the extrusion layers."""
    R, H = (v.length("block radius", block[0]), v.length("block height", block[1]))
    depth = v.real("depth", depth, lo=0.0, hi=0.8 * H, lo_open=True, unit="mm")
    h = v.real("mesh", mesh, lo=MIN_ELEMENT_MM, hi=1.0, unit="mm")
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
    return _Geometry(R, H, depth, h, far, sx, sy, z_max, r_in, r_out, margin,
                     _layers(H, depth + margin, h, far))


def _layers(H: float, fine: float, h: float, far: float) -> tuple[float, ...]:
    """Layer thicknesses (mm): h down to below ``fine``, then growing by 1.5
    up to ``far``, to the block height H."""
    t, layers = 0.0, list[float]()
    while t < H - tol.fem.layer_end:
        dz = h if t < fine else min(far, 1.5 * layers[-1])
        dz = min(dz, H - t)
        layers.append(dz)
        t += dz
    return tuple(layers)


def _check_size(g: _Geometry) -> None:
    """Refuse a model above :data:`MAX_ELEMENTS_3D` before meshing."""
    frac = 0.25 if g.sx and g.sy else 0.5 if g.sx or g.sy else 1.0
    ring = 2 * np.pi * 0.5 * (g.r_in + g.r_out) * frac
    n_est = (ring * (g.r_out - g.r_in + 2 * g.margin) / g.h ** 2
             + np.pi * g.R ** 2 / g.far ** 2) * len(g.layers)
    # the needle's tetrahedra: its front's volume at size h (≈ 6 per h³)
    n_est += 6.0 * frac * np.pi * (g.r_out ** 2 - g.r_in ** 2) * (g.depth + g.margin) / g.h ** 3
    if n_est > MAX_ELEMENTS_3D:
        raise SpecError(f"mesh = {g.h * UM_PER_MM:g} µm needs about {n_est:.0f} elements; "
                        f"allowed up to {MAX_ELEMENTS_3D} (a coarser --mesh-um, a shallower "
                        "--depth-mm)")


def _block_size_field(gmsh: Any, g: _Geometry) -> None:
    """Element size h near the footprint's circles r_in, r_out, growing to ``far``."""
    occ = gmsh.model.occ
    f = gmsh.model.mesh.field
    c1 = occ.addCircle(0, 0, 0, g.r_in)
    c2 = occ.addCircle(0, 0, 0, g.r_out)
    occ.synchronize()
    d = f.add("Distance")
    f.setNumbers(d, "CurvesList", [c1, c2])
    f.setNumber(d, "Sampling", 400)
    th = f.add("Threshold")
    f.setNumber(th, "InField", d)
    f.setNumber(th, "SizeMin", g.h)
    f.setNumber(th, "SizeMax", g.far)
    f.setNumber(th, "DistMin", g.margin)
    f.setNumber(th, "DistMax", g.margin + 4 * g.far)
    bx = f.add("Box")
    for key, val in (("VIn", g.h), ("VOut", g.far), ("XMin", -g.r_in), ("XMax", g.r_in),
                     ("YMin", -g.r_in), ("YMax", g.r_in), ("ZMin", -1), ("ZMax", 1)):
        f.setNumber(bx, key, val)
    mn = f.add("Min")
    f.setNumbers(mn, "FieldsList", [th])
    f.setAsBackgroundMesh(mn)
    for k in ("Mesh.MeshSizeExtendFromBoundary", "Mesh.MeshSizeFromPoints",
              "Mesh.MeshSizeFromCurvature"):
        gmsh.option.setNumber(k, 0)
    occ.remove([(1, c1), (1, c2)])
    occ.synchronize()


def _mesh_block(g: _Geometry, hexahedron: str
                ) -> tuple[IntArray, FloatArray, dict[str, IntArray]]:
    """The tissue block: node tags, coordinates (model frame) and connectivity
    by element type (gmsh node tags)."""
    X0, Z0 = (0.0 if g.sx else -g.R), (0.0 if g.sy else -g.R)
    with gmsh_session() as gmsh:
        occ = gmsh.model.occ
        disk = occ.addDisk(0, 0, 0, g.R, g.R)
        keep = occ.addRectangle(X0, Z0, 0, g.R - X0, g.R - Z0)
        top, _ = occ.intersect([(2, disk)], [(2, keep)])
        occ.synchronize()
        _block_size_field(gmsh, g)
        gmsh.option.setNumber("Mesh.Algorithm", 8)
        gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)
        gmsh.option.setNumber("Mesh.RecombineAll", 1)
        # the top face lies in the x-y plane of gmsh here; extrude along −z, map
        # (x, y, z) of gmsh to model (X, Z, Y) afterwards
        heights = np.cumsum(g.layers) / g.H
        occ.extrude(top, 0, 0, -g.H, numElements=[1] * len(g.layers),
                    heights=heights.tolist(), recombine=True)
        occ.synchronize()
        try:
            gmsh.model.mesh.generate(3)
        except Exception as e:  # gmsh raises a bare Exception with its last error
            raise FemError(f"gmsh could not mesh the block ({_gmsh_msg(e)}); try another "
                           "--mesh-um") from None
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        tags = np.asarray(tags, dtype=np.int64)
        xyz = np.asarray(xyz).reshape(-1, 3)
        tissue_conn: dict[str, IntArray] = {}
        for et, _, nodes in zip(*gmsh.model.mesh.getElements(3)):
            name, k = _GMSH_3D.get(int(et), (None, 0))
            if name is None:
                raise FemError(f"gmsh made 3D elements of type {et}; expected hexahedra, "
                               "prisms or tetrahedra")
            if name == "C3D8":
                name = hexahedron
            tissue_conn[name] = np.asarray(nodes, dtype=np.int64).reshape(-1, k)
    return tags, np.column_stack([xyz[:, 0], xyz[:, 2], xyz[:, 1]]), tissue_conn


def _mesh_needle(g: _Geometry, nv: FloatArray, ff: IntArray
                 ) -> tuple[IntArray, FloatArray, dict[str, IntArray]]:
    """The needle's clipped front (model frame) in tetrahedra: node tags,
    coordinates and connectivity (gmsh node tags)."""
    with gmsh_session() as gmsh:
        _needle_tets(gmsh, nv, ff, g.h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", max(g.h, 0.5 * (g.r_out - g.r_in)))
        try:
            gmsh.model.mesh.generate(3)
        except Exception as e:  # gmsh raises a bare Exception with its last error
            raise FemError(f"gmsh could not tetrahedralise the needle's front to depth "
                           f"{g.depth:g} mm ({_gmsh_msg(e)}); try another --depth-mm or "
                           "--mesh-um") from None
        ntags, nxyz, _ = gmsh.model.mesh.getNodes()
        ntags = np.asarray(ntags, dtype=np.int64)
        nxyz = np.asarray(nxyz).reshape(-1, 3)
        needle_conn: dict[str, IntArray] = {}
        for et, _, nodes in zip(*gmsh.model.mesh.getElements(3)):
            if int(et) != 4:
                raise FemError(f"gmsh made needle elements of type {et}; expected tetrahedra")
            needle_conn["C3D4"] = np.asarray(nodes, dtype=np.int64).reshape(-1, 4)
    if not needle_conn:
        raise FemError("gmsh could not tetrahedralise the needle's front")
    return ntags, nxyz, needle_conn


_Part = tuple[IntArray, FloatArray, dict[str, IntArray]]


def _assemble(g: _Geometry, tissue: _Part, needle: _Part
              ) -> tuple[FloatArray, list[ElementBlock]]:
    """Both parts numbered into one model (the needle reduced by the mirror
    planes, by whole elements: centroids on the kept side), every element
    with a positive volume."""
    nodes: list[FloatArray] = []
    blocks: list[ElementBlock] = []

    def add(part: str, conn_by_type: dict[str, IntArray], tg: IntArray,
            xyz_: FloatArray) -> None:
        eid = 1 + sum(len(b.ids) for b in blocks)
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

    add("tissue", tissue[2], tissue[0], tissue[1])
    ntags, nxyz, needle_conn = needle
    if np.all(np.diff(ntags) > 0):
        P = nxyz[np.searchsorted(ntags, needle_conn["C3D4"])]
    else:
        order = np.argsort(ntags)
        P = nxyz[order][np.searchsorted(ntags[order], needle_conn["C3D4"])]
    ok = np.ones(len(P), dtype=bool)
    if g.sx:
        ok &= P[..., 0].mean(axis=1) >= 0
    if g.sy:
        ok &= P[..., 2].mean(axis=1) >= 0
    add("needle", {"C3D4": needle_conn["C3D4"][ok]}, ntags, nxyz)
    allnodes = np.vstack(nodes)
    _fix_orientation(allnodes, blocks)
    return allnodes, blocks


def _contact_surfaces(g: _Geometry, allnodes: FloatArray, tb: list[ElementBlock],
                      nb: list[ElementBlock], eps: float) -> dict[str, list[tuple[int, int]]]:
    """TISSUE: the block's top faces; NEEDLE: the needle's faces below its
    cut, not on a mirror plane."""
    top = [(e, fc) for e, fc, ns in boundary_faces(tb)
           if np.all(np.abs(allnodes[np.asarray(ns) - 1, 1]) <= eps)]
    y_cut = float(allnodes[np.unique(np.concatenate([b.conn.ravel() for b in nb])) - 1, 1].max())
    near = tol.fem.needle_plane

    def on(ns: tuple[int, ...], axis: int) -> bool:
        return bool(np.all(np.abs(allnodes[np.asarray(ns) - 1, axis]) <= near))

    master = [(e, fc) for e, fc, ns in boundary_faces(nb)
              if np.any(allnodes[np.asarray(ns) - 1, 1] < y_cut - near)
              and not (g.sx and on(ns, 0)) and not (g.sy and on(ns, 2))]
    return {"TISSUE": top, "NEEDLE": master}


def _node_sets(g: _Geometry, allnodes: FloatArray, tb: list[ElementBlock],
               nb: list[ElementBlock], eps: float
               ) -> tuple[dict[str, IntArray], dict[str, tuple[int, ...]]]:
    """The node sets (BASE, SYMX, SYMZ, NEEDLE) and the directions each fixed
    set is held in."""
    tn = np.unique(np.concatenate([b.conn.ravel() for b in tb]))
    T = allnodes[tn - 1]
    nsets = {"BASE": tn[np.abs(T[:, 1] + g.H) <= eps]}
    fixed: dict[str, tuple[int, ...]] = {"BASE": (1, 2, 3)}
    if g.sx:
        nsets["SYMX"] = tn[np.abs(T[:, 0]) <= eps]
        fixed["SYMX"] = (1,)
    if g.sy:
        nsets["SYMZ"] = tn[np.abs(T[:, 2]) <= eps]
        fixed["SYMZ"] = (3,)
    nsets["NEEDLE"] = np.unique(np.concatenate([b.conn.ravel() for b in nb]))
    return nsets, fixed


def _symmetry_tris(allnodes: FloatArray, tb: list[ElementBlock], sym_axis: int | None,
                   eps: float) -> list[list[int]] | None:
    """Tissue faces on the symmetry plane as triangles (node numbers), for the
    contour picture; None without a symmetry plane."""
    if sym_axis is None:
        return None
    sym_tris = []
    for _e, _fc, ns in boundary_faces(tb):
        ns_ = list(ns)
        if np.all(np.abs(allnodes[np.asarray(ns_) - 1, sym_axis]) <= eps):
            sym_tris += [[ns_[0], ns_[i], ns_[i + 1]] for i in range(1, len(ns_) - 1)]
    return sym_tris


def _signed_volumes(P: FloatArray, etype: str) -> FloatArray:
    if etype == "C3D4":
        a, b, c, d = P[:, 0], P[:, 1], P[:, 2], P[:, 3]
    elif etype == "C3D6":
        a, b, c, d = P[:, 0], P[:, 1], P[:, 2], P[:, 3]
    else:
        a, b, c, d = P[:, 0], P[:, 1], P[:, 3], P[:, 4]
    vol: FloatArray = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a))
    return vol


def _fix_orientation(nodes: FloatArray, blocks: list[ElementBlock]) -> None:
    """Renumber elements with a negative volume (mirror their node order)."""
    flip = {"C3D4": [0, 2, 1, 3], "C3D6": [0, 2, 1, 3, 5, 4],
            "C3D8": [0, 3, 2, 1, 4, 7, 6, 5], "C3D8I": [0, 3, 2, 1, 4, 7, 6, 5]}
    for b in blocks:
        vol = _signed_volumes(nodes[b.conn - 1], b.etype)
        neg = vol < 0
        if np.any(neg):
            b.conn[neg] = b.conn[neg][:, flip[b.etype]]
