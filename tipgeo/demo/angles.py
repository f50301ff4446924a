"""The angles part of ``tipgeo demo``: angle tables of every sample
(``angles.csv``, ``angles.json``) and the angle curves overlaid
(``angles-*.png``, like thesis Figs. 3.5–3.10). Angles in degrees, lengths mm."""

from __future__ import annotations

from pathlib import Path

from ..atomic import write_text_atomic
from ..jsonio import dumps as _dumps
from ..paths import inside
from ..presets import preset
from ..progress import LineSink

__all__ = ["ANGLE_GROUPS", "angle_outputs"]


#: Groups of samples whose angle curves are overlaid in one picture.
ANGLE_GROUPS = {
    "angles-helical-vs-bevel": ["helical-14G", "bevel-14G-xi14.5"],
    "angles-bevels": ["bevel-14G-xi15", "bevel-14G-xi45", "bevel-14G-xi75"],
    "angles-multiplane": ["bevel-14G-xi15", "twoplane-14G-xi15", "threeplane-14G-xi15",
                          "lancet-14G"],
    "angles-conical-and-punch": ["conical-14G-theta15", "punch-plain", "punch-C2"],
}


def angle_outputs(out: Path, names: list[str], pictures: bool, log: LineSink | None) -> list[str]:
    """Angle tables (CSV) of every sample, and the overlaid angle plots."""
    from ..angles import analyze

    reports = {n: analyze(preset(n), method="fourier") for n in names}
    text = ""
    for k, rep in enumerate(reports.values()):
        t = rep.to_csv(1.0)
        text += t if k == 0 else t.split("\n", 1)[1]
    write_text_atomic(out / "angles.csv", text)
    files = [str(out / "angles.csv")]
    summaries = {n: r.summary() for n, r in reports.items()}
    write_text_atomic(out / "angles.json", _dumps(summaries) + "\n")
    files.append(str(out / "angles.json"))
    if pictures:
        from ..plot import plot_angles

        for fname, group in ANGLE_GROUPS.items():
            reps = [reports[n] for n in group if n in reports]
            if reps:
                files.append(str(plot_angles(reps, inside(out, fname, ".png"))))
    if log is not None:
        print(f"angles: {len(reports)} tips analysed, {len(files)} files", file=log, flush=True)
    return files


