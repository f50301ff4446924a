"""The optimiser part of ``tipgeo demo``: the thesis's helical study (§3.4)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..optimize.executors import SerialExecutor
from ..optimize.presets import study_preset
from ..optimize.study import run_study
from ..paths import inside

__all__ = ["demo_outputs"]


def demo_outputs(out_dir: Path, log: Callable[[str], None] | None = None) -> list[str]:
    """Run the thesis's helical study into ``out_dir/helical-study/`` in this
    process, without a cache; return the files written.

    The design's candidate grid screened by validation (157 of 441 specs
    validated, ~0.02–0.06 s each), 25 admissible configurations analysed,
    seven GP fits, the objectives' multi-start search (54 validations: the
    screened grid answers for the region it saw refused), adaptive infill at
    the optima, three optima built and analysed, the pictures: about 17 s of
    CPU on one core.
    """

    cfg = study_preset("helical-study")
    rep = run_study(cfg, inside(out_dir, cfg.name), executor=SerialExecutor(), cache=False,
                    progress=False, log=log or (lambda s: None))
    files: list[str] = rep["files"]
    return files
