"""Aerotech A3200 (AeroBasic) laser G-code for micro-serrations (thesis
chapter 5, Appendix C): emitter, parser, interpreter and ablation simulator.

Machine frame (mm, degrees): X along the punch rim, Y along the punch axis
(+Y into the material), C the punch's rotation (+C = +γ), the beam radial
through the wall. See :mod:`gcode.ablation` for the mapping onto the
cannula frame.

``import gcode`` is light: the simulator's heavy parts load on use.
"""

from .emitter import LaserParams, emit_program
from .errors import GCodeError
from .interpreter import Limits, Segment, Toolpath, interpret
from .parser import parse
from .pipeline import LaserCheck, laser_check, make_limits, read_program, write_laser_outputs

__all__ = ["GCodeError", "parse", "interpret", "Toolpath", "Segment", "Limits",
           "LaserParams", "emit_program", "LaserCheck", "laser_check", "make_limits",
           "read_program", "write_laser_outputs"]
