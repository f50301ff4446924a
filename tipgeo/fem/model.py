"""One finite-element model of a rigid needle pushed into a tissue block, and
its two decks: CalculiX (``ccx``) and Abaqus (the Appendix B layout).

Model frame (both kinds): the needle moves along −Y into the block, whose top
face is Y = 0 and which fills Y < 0; the needle's most advanced point starts
at Y = 0. The needle's cannula frame maps to it by Y = z_max − z (axisymmetric:
X = r). Units mm, N, s, MPa. For ``axisymmetric`` models X is the radius and
CalculiX expands each element to a 2° wedge: reaction forces are for 2°
(``force_scale`` = 180 gives the whole ring); for ``3d`` models reduced by
symmetry ``force_scale`` restores the whole needle.

The needle is meshed but rigid: CalculiX prescribes every needle node's
displacement (it accepts neither analytical rigid surfaces nor ``*RIGID
BODY`` on ``R3D3``); the Abaqus deck makes the same nodes a ``*Rigid Body``
with a reference node, as in Appendix B.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..arrays import ArrayLike, FloatArray, IntArray
from ..errors import SpecError
from ..names import one_line
from ..tolerances import tol
from .material import FemMaterial

__all__ = ["ElementBlock", "FemModel", "FACE_NODES", "boundary_faces", "check_output_depths",
           "contact_penalty", "UM_PER_MM"]

#: Local node indices of each face S1… of an element type (CalculiX and
#: Abaqus numbering).
FACE_NODES: dict[str, tuple[tuple[int, ...], ...]] = {
    "CAX3": ((0, 1), (1, 2), (2, 0)),
    "CAX4": ((0, 1), (1, 2), (2, 3), (3, 0)),
    "C3D4": ((0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0)),
    "C3D6": ((0, 1, 2), (3, 5, 4), (0, 3, 4, 1), (1, 4, 5, 2), (2, 5, 3, 0)),
    "C3D8": ((0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3),
             (3, 7, 4, 0)),
}
FACE_NODES["C3D8I"] = FACE_NODES["C3D8"]

#: µm per mm (element sizes in reports).
UM_PER_MM = 1e3

#: Smallest time increment of an erosion step, as a fraction of the step
#: (CalculiX's own default).
ERODE_MIN_INCREMENT = 1e-5

#: Ceiling on the Abaqus deck's smallest time increment (fraction of the step).
ABAQUS_MIN_INCREMENT = 1e-9


def check_output_depths(output_depths: tuple[float, ...], depth: float) -> tuple[float, ...]:
    """The depths (mm) with stresses in the .frd, each in (0, ``depth``]."""
    from .. import validate as v

    return tuple(v.real("output depth", d, lo=0.0, hi=depth, lo_open=True, unit="mm")
                 for d in output_depths)


def contact_penalty(factor: float, E0: float, h: float, stiffness: float | None) -> float:
    """The contact's penalty stiffness (MPa/mm): ``stiffness`` when given,
    else ``factor`` × E₀ / h (E₀ in MPa, h in mm)."""
    from .. import validate as v

    if stiffness is None:
        return factor * E0 / h
    return v.real("contact_stiffness", stiffness, lo=0.0, lo_open=True, unit="MPa/mm")


#: Abaqus names of the same elements (hybrid, reduced integration in 2D, as
#: the thesis's CAX4RH of Appendix B2).
_ABAQUS_TYPE = {"CAX3": "CAX3H", "CAX4": "CAX4RH", "C3D4": "C3D4H", "C3D6": "C3D6H",
                "C3D8": "C3D8RH", "C3D8I": "C3D8RH"}


@dataclass
class ElementBlock:
    """Elements of one type in one part.

    Attributes
    ----------
    etype : str — a key of :data:`FACE_NODES`
    part : str — ``tissue`` or ``needle``
    ids : (m,) int — element numbers (1-based, unique in the model)
    conn : (m, k) int — node numbers (1-based)
    """

    etype: str
    part: str
    ids: IntArray
    conn: IntArray


def boundary_faces(blocks: list[ElementBlock]) -> list[tuple[int, int, tuple[int, ...]]]:
    """Faces used by one element only: (element id, face number 1…, node ids)."""
    seen: dict[tuple[int, ...], list[tuple[int, int, tuple[int, ...]]]] = {}
    for b in blocks:
        for f, loc in enumerate(FACE_NODES[b.etype], 1):
            nodes = b.conn[:, loc]
            for eid, row in zip(b.ids.tolist(), nodes.tolist()):
                key = tuple(sorted(row))
                seen.setdefault(key, []).append((eid, f, tuple(row)))
    return [v[0] for v in seen.values() if len(v) == 1]


@dataclass
class FemModel:
    """A needle-into-tissue model (see the module docstring for the frame).

    Attributes
    ----------
    kind : ``axisymmetric`` | ``3d``
    name : str
    nodes : (n, 2) or (n, 3) float — mm, model frame; node i is row i − 1
    blocks : list of ElementBlock
    nsets : dict name → (k,) int — ``BASE``, ``NEEDLE`` and the symmetry sets
        (``AXIS`` in 2D; ``SYMX``, ``SYMY`` in 3D: nodes on X = 0, Y… see 3D)
    fixed : dict nset → tuple of dofs held at 0
    surfaces : dict name → list of (element id, face number) — ``TISSUE``
        (slave) and ``NEEDLE`` (master)
    material : FemMaterial
    friction : float — Coulomb coefficient
    depth : float — needle travel, mm
    penalty : float — contact stiffness, MPa/mm
    force_scale : float — reaction × this = whole-needle force
    increments : (initial, minimum, maximum) step-time increments
    output_depths : tuple of float — depths (mm) with stresses in the .frd
    contact : ``surface`` (CalculiX surface-to-surface penalty contact) |
        ``node`` (node-to-surface)
    info : dict — element size, counts, sources (for reports); keys starting
        with ``_`` hold geometry for pictures
    stages : tuple of (depth, removed element ids, node surface) — an
        erosion model's steps: step k pushes the needle to ``depth`` (mm),
        first removing those tissue elements (``*MODEL CHANGE``) and
        switching on the contact of that node surface of the tissue (the
        nodes exposed once they are gone, slave to the needle's faces) in
        place of the previous one; empty: one step to ``depth``
    node_surfaces : dict name → (k,) int — node surfaces (``TYPE=NODE``)
    slave : ``needle`` | ``tissue`` — whose nodes are the contact's slaves
        (the other part's faces the master surface)
    stick_slope : float, optional — the friction's stick slope (tangential
        penalty stiffness before slip), MPa/mm; default ``penalty``
    """

    kind: str
    name: str
    nodes: FloatArray
    blocks: list[ElementBlock]
    nsets: dict[str, IntArray]
    fixed: dict[str, tuple[int, ...]]
    surfaces: dict[str, list[tuple[int, int]]]
    material: FemMaterial
    friction: float
    depth: float
    penalty: float
    force_scale: float
    increments: tuple[float, float, float]
    output_depths: tuple[float, ...] = ()
    contact: str = "surface"
    slave: str = "needle"
    info: dict[str, Any] = field(default_factory=dict)
    stages: tuple[tuple[float, IntArray, str], ...] = ()
    node_surfaces: dict[str, IntArray] = field(default_factory=dict)
    stick_slope: float | None = None

    def public_info(self) -> dict[str, Any]:
        """``info`` without the geometry kept for pictures (keys starting
        with ``_``)."""
        return {k: v for k, v in self.info.items() if not k.startswith("_")}

    @property
    def dim(self) -> int:
        return 2 if self.kind == "axisymmetric" else 3

    @property
    def n_elements(self) -> int:
        return int(sum(len(b.ids) for b in self.blocks))

    def part_nodes(self, part: str) -> IntArray:
        """Node numbers (1-based, sorted) of ``part``."""
        return np.unique(np.concatenate([b.conn.ravel() for b in self.blocks
                                         if b.part == part]))

    # ----------------------------------------------------------------- decks
    def _node_lines(self, ids: IntArray | None = None) -> str:
        ids = np.arange(1, len(self.nodes) + 1) if ids is None else ids
        xyz = self.nodes[ids - 1]
        if self.dim == 2:
            return "".join(f"{i}, {x:.9f}, {y:.9f}\n" for i, (x, y) in
                           zip(ids.tolist(), xyz.tolist()))
        return "".join(f"{i}, {x:.9f}, {y:.9f}, {z:.9f}\n" for i, (x, y, z) in
                       zip(ids.tolist(), xyz.tolist()))

    @staticmethod
    def _id_lines(ids: ArrayLike) -> str:
        rows = np.asarray(ids).tolist()
        return "".join(", ".join(map(str, rows[i:i + 16])) + "\n"
                       for i in range(0, len(rows), 16))

    def _surface(self, name: str, prefix: str = "") -> str:
        by_face: dict[int, list[int]] = {}
        for e, f in self.surfaces[name]:
            by_face.setdefault(f, []).append(e)
        out = ""
        for f, es in sorted(by_face.items()):
            out += f"*ELSET, ELSET={prefix}S_{name}_{f}\n" + self._id_lines(sorted(es))
        out += f"*SURFACE, NAME={name}, TYPE=ELEMENT\n"
        out += "".join(f"{prefix}S_{name}_{f}, S{f}\n" for f in sorted(by_face))
        return out

    def step_times(self) -> list[float]:
        """Output times: every largest increment and each output depth."""
        n = int(np.ceil(1.0 / self.increments[2] - tol.fem.ceil_slack))
        t = np.r_[np.linspace(0.0, 1.0, n + 1)[1:], [d / self.depth for d in self.output_depths]]
        return sorted({round(float(x), 12) for x in t})

    def header(self) -> str:
        lines = [f"tipgeo finite-element model '{one_line(self.name)}' ({self.kind}); units mm, "
                 "N, s, MPa",
                 "frame: needle moves along -Y into the block (top face Y = 0); "
                 + ("X = radius (axisymmetric)" if self.dim == 2 else "Z completes a right-"
                    "handed frame")]
        lines += [f"{k}: {v}" for k, v in self.public_info().items()]
        # every user string on one comment line: no line break can start a keyword
        return "".join(f"** {one_line(x)}\n" for x in lines)

    def ccx_deck(self) -> str:
        """The CalculiX input deck (text)."""
        o = ["*HEADING\n", f"tipgeo {self.kind} needle insertion: {one_line(self.name)}\n",
             self.header()]
        o.append("*NODE, NSET=NALL\n" + self._node_lines())
        o += [self._ccx_part(part) for part in ("tissue", "needle")]
        for name, ids in self.nsets.items():
            o.append(f"*NSET, NSET={name}\n" + self._id_lines(ids))
        for name in self.surfaces:
            o.append(self._surface(name))
        o.append("*MATERIAL, NAME=TISSUE\n" + self.material.card())
        o.append("*MATERIAL, NAME=RIGID\n*ELASTIC\n210000, 0.3\n")
        o.append("*SOLID SECTION, ELSET=TISSUE, MATERIAL=TISSUE\n")
        o.append("*SOLID SECTION, ELSET=NEEDLE, MATERIAL=RIGID\n")
        o.append(self._ccx_interaction())
        masters = list(dict.fromkeys(m for _, _, m in self.stages))
        o.append(self._ccx_contact_pairs(masters))
        o.append("*BOUNDARY\n" + "".join(f"{ns}, {d}, {d}, 0\n" for ns, dofs in
                                         self.fixed.items() for d in dofs))
        side = [d for d in range(1, self.dim + 1) if d != 2]
        o.append("".join(f"NEEDLE, {d}, {d}, 0\n" for d in side))
        if self.stages:
            return "".join(o) + self._erosion_steps(masters)
        return "".join(o) + self._ccx_step()

    def _ccx_part(self, part: str) -> str:
        """The ``*ELEMENT`` blocks of ``part`` and its element set."""
        o, sets = [], []
        for b in self.blocks:
            if b.part != part:
                continue
            es = f"{part.upper()}_{b.etype}"
            sets.append(es)
            o.append(f"*ELEMENT, TYPE={b.etype}, ELSET={es}\n")
            o.append("".join(f"{e}, " + ", ".join(map(str, r)) + "\n"
                             for e, r in zip(b.ids.tolist(), b.conn.tolist())))
        o.append(f"*ELSET, ELSET={part.upper()}\n" + ", ".join(sets) + "\n")
        return "".join(o)

    def _ccx_interaction(self) -> str:
        """The penalty contact's ``*SURFACE INTERACTION`` with its friction."""
        h = float(self.info.get("element_size_um", 10.0)) * 1e-3  # µm to mm
        out = ("*SURFACE INTERACTION, NAME=CONTACT\n"
               "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n"
               + (f"{self.penalty:.8g}\n" if self.contact == "surface" else
                  f"{self.penalty:.8g}, {1e-3 * self.penalty * h:.6g}, {0.1 * h:.6g}\n"))
        if self.friction > 0:
            stick = self.penalty if self.stick_slope is None else self.stick_slope
            out += f"*FRICTION\n{self.friction:.6g}, {stick:.8g}\n"
        return out

    def _ccx_contact_pairs(self, masters: list[str]) -> str:
        """Node surfaces and ``*CONTACT PAIR`` cards (the erosion's one per
        exposed layer)."""
        o = [f"*SURFACE, NAME={name}, TYPE=NODE\n"
             + "".join(f"{i}\n" for i in np.asarray(ids).tolist())
             for name, ids in self.node_surfaces.items()]
        kind = "SURFACE TO SURFACE\n" if self.contact == "surface" else "NODE TO SURFACE\n"
        if self.stages:
            kind = "NODE TO SURFACE\n"
        o.append("*CONTACT PAIR, INTERACTION=CONTACT, TYPE=" + kind
                 + ("NEEDLE, TISSUE\n" if self.slave == "needle" else "TISSUE, NEEDLE\n"))
        o += [f"*CONTACT PAIR, INTERACTION=CONTACT, TYPE=NODE TO SURFACE\n{m}, NEEDLE\n"
              for m in masters]
        return "".join(o)

    def _ccx_step(self) -> str:
        """The one static step to ``depth`` with its output times."""
        o = ["*TIME POINTS, NAME=OUT\n" + "".join(f"{t:.12g}\n" for t in self.step_times())]
        dt0, dtmin, dtmax = self.increments
        o.append("*STEP, NLGEOM, INC=100000\n"
                 "*CONTROLS, PARAMETERS=TIME INCREMENTATION\n8, 16, 9, 40, 10, 4, , 10\n"
                 "*STATIC\n"
                 f"{dt0:.6g}, 1.0, {dtmin:.6g}, {dtmax:.6g}\n")
        o.append(f"*BOUNDARY\nNEEDLE, 2, 2, {-self.depth:.9f}\n")
        o.append("*NODE PRINT, NSET=NEEDLE, TOTALS=ONLY, TIME POINTS=OUT\nRF\n"
                 "*NODE FILE, TIME POINTS=OUT\nU\n*EL FILE, TIME POINTS=OUT\nS\n*END STEP\n")
        return "".join(o)

    @staticmethod
    def _pair(slave: str) -> str:
        return f"{slave}, NEEDLE\n"

    def _erosion_steps(self, masters: list[str]) -> str:
        """The steps of an erosion model (see ``stages``): step times add up
        to 1 at ``depth``, so total time × depth is the needle's depth."""
        o: list[str] = []
        prev_d, prev_m = 0.0, ""
        outs = {round(d, 9) for d in self.output_depths} | {round(self.depth, 9)}
        for k, (d, removed, master) in enumerate(self.stages):
            period = (d - prev_d) / self.depth
            o.append("*STEP, NLGEOM, INC=100000\n"
                     "*CONTROLS, PARAMETERS=TIME INCREMENTATION\n8, 16, 9, 40, 10, 4, , 10\n"
                     f"*STATIC\n{period:.9g}, {period:.9g}, {ERODE_MIN_INCREMENT * period:.6g}, "
                     f"{period:.9g}\n")
            if len(removed):
                o.append("*MODEL CHANGE, TYPE=ELEMENT, REMOVE\n" + self._id_lines(removed))
            if k == 0:
                o += [f"*MODEL CHANGE, TYPE=CONTACT PAIR, REMOVE\n{self._pair(m)}"
                      for m in masters if m != master]
            elif master != prev_m:
                o.append(f"*MODEL CHANGE, TYPE=CONTACT PAIR, REMOVE\n{self._pair(prev_m)}"
                         f"*MODEL CHANGE, TYPE=CONTACT PAIR, ADD\n{self._pair(master)}")
            o.append(f"*BOUNDARY\nNEEDLE, 2, 2, {-d:.9f}\n")
            o.append("*NODE PRINT, NSET=NEEDLE, TOTALS=ONLY\nRF\n")
            f = 1 if round(d, 9) in outs else 0
            o.append(f"*NODE FILE, FREQUENCY={f}\nU\n*EL FILE, FREQUENCY={f}\nS\n*END STEP\n")
            prev_d, prev_m = d, master
        return "".join(o)

    def abaqus_deck(self) -> str:
        """The same model as an Abaqus/Standard deck in the layout of the
        thesis's Appendix B: parts ``Tissue`` and ``Needle``, an assembly with
        one instance each, the needle a ``*Rigid Body`` (its boundary as
        RAX2/R3D3 elements) driven through its reference node, a
        ``*Contact Pair`` with the friction coefficient, and one static step
        with stabilisation (as B2). Not for erosion models (``stages``):
        Abaqus remeshes adaptively instead, as the thesis did."""
        if self.stages:
            raise SpecError("the Abaqus deck is not written for the erosion cut (Abaqus "
                           "remeshes adaptively instead, as the thesis did); drop --abaqus "
                           "or --cut erosion")
        o = ["*Heading\n", f"tipgeo {self.kind} needle insertion: {one_line(self.name)}\n",
             self.header(),
             "*Preprint, echo=NO, model=NO, history=NO, contact=NO\n",
             self._abaqus_tissue(), self._abaqus_needle(), self._abaqus_assembly()]
        o.append("*Material, name=Tissue\n*Density\n1e-06,\n" + self.material.card())
        o.append("*Surface Interaction, name=IntProp-1\n1.,\n")
        o.append(f"*Friction, slip tolerance=0.005\n{self.friction:.6g},\n"
                 "*Surface Behavior, pressure-overclosure=HARD\n")
        o.append("*Boundary\n" + "".join(f"{ns}, {d}, {d}\n" for ns, dofs in
                                         self.fixed.items() for d in dofs))
        o.append("*Contact Pair, interaction=IntProp-1, type=SURFACE TO SURFACE\n"
                 "TISSUE, Needle-1.NEEDLE\n")
        return "".join(o) + self._abaqus_step()

    def _abaqus_tissue(self) -> str:
        """The ``Tissue`` part."""
        tissue = [b for b in self.blocks if b.part == "tissue"]
        o = ["*Part, name=Tissue\n*Node\n" + self._node_lines(self.part_nodes("tissue"))]
        for b in tissue:
            o.append(f"*Element, type={_ABAQUS_TYPE[b.etype]}\n")
            o.append("".join(f"{e}, " + ", ".join(map(str, r)) + "\n"
                             for e, r in zip(b.ids.tolist(), b.conn.tolist())))
        o.append("*Elset, elset=TISSUE\n" + self._id_lines(np.concatenate([b.ids for b in
                                                                            tissue])))
        o.append("*Solid Section, elset=TISSUE, material=Tissue\n*End Part\n")
        return "".join(o)

    def _rigid_faces(self) -> list[list[int]]:
        """The needle's contact faces as node lists (1-based), sorted."""
        conn_of = {}
        for b in self.blocks:
            if b.part == "needle":
                for e, r in zip(b.ids.tolist(), b.conn.tolist()):
                    conn_of[e] = (b.etype, r)
        rig = []
        for e, f in sorted({(e, f) for e, f in self.surfaces["NEEDLE"]}):
            et, r = conn_of[e]
            rig.append([r[i] for i in FACE_NODES[et][f - 1]])
        return rig

    def _abaqus_needle(self) -> str:
        """The ``Needle`` part: its contact faces as rigid elements (RAX2,
        R3D3) of a ``*Rigid Body`` with a reference node above it."""
        rig = self._rigid_faces()
        nnodes = np.unique(np.concatenate([np.asarray(x) for x in rig]))
        ref = int(len(self.nodes) + 1)
        top = self.nodes[nnodes - 1].max(axis=0)
        refxyz = [0.0] * self.dim
        refxyz[1] = float(top[1])
        o = ["*Part, name=Needle\n*Node\n" + self._node_lines(nnodes)]
        o.append(f"{ref}, " + ", ".join(f"{c:.9f}" for c in refxyz) + "\n")
        first = self.n_elements + 1
        if self.dim == 2:
            o.append("*Element, type=RAX2\n")
            o.append("".join(f"{first + i}, {a}, {b}\n" for i, (a, b) in enumerate(rig)))
            n_rig = len(rig)
        else:
            tri = [(r[0], r[1], r[2]) for r in rig] + [(r[0], r[2], r[3]) for r in rig
                                                       if len(r) == 4]
            o.append("*Element, type=R3D3\n")
            o.append("".join(f"{first + i}, {a}, {b}, {c}\n" for i, (a, b, c) in
                             enumerate(tri)))
            n_rig = len(tri)
        o.append(f"*Elset, elset=RIGID, generate\n{first}, {first + n_rig - 1}, 1\n")
        o.append(f"*Nset, nset=RefPt\n{ref}\n*Surface, type=ELEMENT, name=NEEDLE\nRIGID, SPOS\n"
                 "*Rigid Body, ref node=RefPt, elset=RIGID\n*End Part\n")
        return "".join(o)

    def _abaqus_assembly(self) -> str:
        """The assembly: one instance of each part, the node sets and the
        tissue's contact surface."""
        o = ["*Assembly, name=Assembly\n*Instance, name=Tissue-1, part=Tissue\n"
             "*End Instance\n*Instance, name=Needle-1, part=Needle\n*End Instance\n"]
        for name, ids in self.nsets.items():
            if name == "NEEDLE":
                continue
            o.append(f"*Nset, nset={name}, instance=Tissue-1\n" + self._id_lines(ids))
        o.append(self._surface("TISSUE").replace("*ELSET, ELSET=", "*Elset, instance=Tissue-1, "
                                                 "elset="))
        o.append("*End Assembly\n")
        return "".join(o)

    def _abaqus_step(self) -> str:
        """The static step with stabilisation, the reference node driven."""
        dt0, dtmin, dtmax = self.increments
        o = ["*Step, name=Insertion, nlgeom=YES, inc=1000000\n"
             "*Static, stabilize, allsdtol=0.05, continue=YES\n"
             f"{dt0:.6g}, 1., {min(dtmin, ABAQUS_MIN_INCREMENT):.6g}, {dtmax:.6g}\n"]
        rot = (6,) if self.dim == 2 else (4, 5, 6)
        o.append("*Boundary\n" + "".join(f"Needle-1.RefPt, {d}, {d}\n" for d in
                                         [d for d in range(1, self.dim + 1) if d != 2] + list(rot)))
        o.append(f"Needle-1.RefPt, 2, 2, {-self.depth:.9f}\n")
        o.append("*Output, field\n*Node Output\nU, RF\n*Element Output\nS\n"
                 "*Output, history\n*Node Output, nset=Needle-1.RefPt\nRF2, U2\n*End Step\n")
        return "".join(o)
