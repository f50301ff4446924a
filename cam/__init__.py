"""Five-axis needle-grinding CAM (thesis §2.3.1): machine model and frames,
set-up (inverse kinematics), axis programs (CSV/JSON), ISO G-code, set-up
sheets, and a material-removal simulator that closes the loop with the angle
analysis.

Frames (cannula, needle OXYZ, wheel O*X*Y*Z* of eq. 2.31) and axes (t1, t2,
r3, r4, r5): see :mod:`cam.machine`. mm, degrees in programs, rad inside.
"""

from .machine import CamError, Machine
from .pipeline import GrindResult, grind, write_grind_outputs
from .program import GrindProgram, make_program, setup_faces
from .simulate import compare_with_cad, simulate

__all__ = ["CamError", "Machine", "GrindProgram", "make_program", "setup_faces", "simulate",
           "compare_with_cad", "grind", "GrindResult", "write_grind_outputs"]
