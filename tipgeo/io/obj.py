"""Wavefront OBJ (``.obj``): full double precision, one group per label.

Written in the cannula frame (+z along the needle axis towards the tip, heel at
z = 0) in mm. A ``g`` line (``g outer``, ``g cut:bevel``) starts wherever the
label changes along the face list, so the face order is kept; ``# label <id>
<name>`` comments hold the exact label names. The reader restores the labels
of an OBJ written here (first line :data:`OBJ_MAGIC`) and reads any other OBJ
through trimesh without labels.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SpecError
from ..tip import Tip
from .common import FRAME_NOTE
from .load import labels_from_ids, read_trimesh
from .registry import ExportOptions, LoadedMesh, register_exporter, register_importer

__all__ = ["OBJ_MAGIC", "group_names", "read_obj", "write_obj"]

#: First line of every OBJ written here; the reader restores labels only then.
OBJ_MAGIC = "# tipgeo OBJ"


def group_names(names: Sequence[str]) -> list[str]:
    """One whitespace-free, unique group token per label."""
    out: list[str] = []
    for k, n in enumerate(names):
        g = re.sub(r"\s+", "_", n)
        out.append(g if g not in out else f"{g}~{k}")
    return out


def write_obj(tip: Tip, tmp: Path, opts: ExportOptions) -> None:
    """Write ``tip`` as a Wavefront OBJ, full double precision, a ``g`` group
    line wherever the label changes and ``# label <id> <name>`` comments."""
    v, f, lab = tip.vertices, tip.faces + 1, tip.label_ids
    groups = group_names(tip.label_names)
    with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(f"{OBJ_MAGIC} mesh: one group per label\n# name {opts.name}\n"
                 f"# units mm; {FRAME_NOTE}\n")
        fh.write("".join(f"# label {k} {n}\n" for k, n in enumerate(tip.label_names)))
        fh.write("o " + re.sub(r"\s+", "_", opts.name) + "\n")
        fh.write("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in v.tolist()))
        # a `g` line wherever the label changes: keeps the face order
        starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
        ends = np.r_[starts[1:], len(lab)]
        for s, e in zip(starts.tolist(), ends.tolist(), strict=True):
            fh.write(f"g {groups[lab[s]]}\n")
            fh.write("".join(f"f {a} {b} {c}\n" for a, b, c in f[s:e].tolist()))


@dataclass
class _ObjReader:
    """The state of reading an OBJ written here: label names from ``# label``
    comments, the mesh name, vertex lines, triangles and their labels."""

    where: str
    named: dict[int, str] = field(default_factory=dict)
    name: str | None = None
    vs: list[str] = field(default_factory=list)
    faces: list[list[int]] = field(default_factory=list)
    fl: list[int] = field(default_factory=list)
    group: int | None = None

    def comment(self, line: str) -> None:
        parts = line[1:].split(None, 2)
        if len(parts) == 3 and parts[0] == "label" and parts[1].isdigit():
            self.named[int(parts[1])] = parts[2].strip()
        elif len(parts) >= 2 and parts[0] == "name":
            self.name = line[1:].split(None, 1)[1].strip()

    def face(self, rest: str, ln: int) -> None:
        """A face line, fan-triangulated, each triangle with the group's label."""
        idx = []
        for t in rest.split():
            k = int(t.split("/", 1)[0])
            idx.append(k - 1 if k > 0 else len(self.vs) + k)
        if len(idx) < 3:
            raise SpecError(f"path '{self.where}' line {ln}: face with {len(idx)} vertices")
        for j in range(1, len(idx) - 1):  # fan-triangulate polygons
            self.faces.append([idx[0], idx[j], idx[j + 1]])
            self.fl.append(-1 if self.group is None else self.group)

    def line(self, line: str, ln: int) -> None:
        if not line or line.startswith("#"):
            self.comment(line)
            return
        tag, _, rest = line.partition(" ")
        if tag == "v":
            self.vs.append(rest)
        elif tag == "f":
            self.face(rest, ln)
        elif tag == "g":
            self.group = _obj_group_id(rest.strip(), self.named)

    def mesh(self) -> LoadedMesh:
        p = self.where
        if not self.vs:
            raise SpecError(f"path '{p}' has no vertices")
        vals = np.array(" ".join(self.vs).split(), dtype=np.float64)
        if len(vals) != 3 * len(self.vs):
            raise SpecError(f"path '{p}': vertex lines must hold exactly x y z")
        mesh = LoadedMesh(vals.reshape(-1, 3),
                          np.array(self.faces, dtype=np.int64).reshape(-1, 3), name=self.name)
        labels = np.array(self.fl, dtype=np.int64)
        if len(labels) and labels.min() >= 0:
            mesh.label_ids, mesh.label_names = labels_from_ids(labels, self.named, len(labels),
                                                               f"path '{p}'")
        return mesh


def read_obj(p: Path) -> LoadedMesh:
    """Read an OBJ written by :func:`write_obj` directly (groups and ``# label``
    comments give the labels; polygons are fan-triangulated), any other OBJ
    through trimesh without labels."""
    with open(p, "rb") as fh:
        first = fh.readline()
    if not first.decode("utf-8", "replace").startswith(OBJ_MAGIC):
        return read_trimesh(p)  # not ours: no labels
    text = p.read_text(encoding="utf-8", errors="replace")
    reader = _ObjReader(str(p))
    for ln, line in enumerate(text.splitlines(), 1):
        reader.line(line, ln)
    return reader.mesh()


def _obj_group_id(token: str, named: dict[int, str]) -> int:
    groups = group_names([named.get(k, f"label{k}") for k in range(max(named, default=-1)
                                                                          + 1)])
    if token in groups:
        return groups.index(token)
    named[len(groups)] = token  # a group without a `# label` line: a new label
    return len(groups)


register_exporter(".obj", write_obj)
register_importer(".obj", read_obj)
