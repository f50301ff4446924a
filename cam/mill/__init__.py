"""Three-axis milling of needle tips on a vertical machining centre (thesis
§3.2): machine and end mills (:mod:`.machine`), OpenCAMLib toolpaths
(:mod:`.toolpath`), posts as tables (:mod:`.post`), a material-removal
simulator that reads the G-code back (:mod:`.simulate`), the checks a
program passes before it is written (:mod:`.check`) and the pipeline
(:mod:`.pipeline`). Frames: :mod:`cam.mill.machine`; mm, rad inside, µm and
degrees in reports, feeds mm/min.
"""

from .check import check_program
from .machine import DEFAULT_TOOL, TOOL_KINDS, EndMill, MillMachine, parse_tool
from .pipeline import MillResult, mill, setup_sheet, write_mill_outputs
from .post import HAAS, POSTS, Post, post_program
from .simulate import (
    GCodeMoves,
    MilledTip,
    compare_milled,
    read_gcode,
    simulate_mill,
    sweep_heights,
)
from .toolpath import (
    MillParams,
    MillSetup,
    MillToolpath,
    cad_height,
    plan_toolpaths,
    planar_stepover,
)

__all__ = ["MillMachine", "EndMill", "TOOL_KINDS", "DEFAULT_TOOL", "parse_tool", "MillParams",
           "MillSetup", "MillToolpath", "cad_height", "plan_toolpaths", "planar_stepover", "Post",
           "POSTS", "HAAS", "post_program", "GCodeMoves", "read_gcode", "MilledTip",
           "simulate_mill", "sweep_heights", "compare_milled", "MillResult", "mill",
           "setup_sheet", "write_mill_outputs", "check_program"]
