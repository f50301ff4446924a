"""Five-axis needle-grinding CAM (kinematics, programs, simulator).

Frames: the needle frame OXYZ and the wheel frame O*X*Y*Z* of thesis
eq. 2.31; mm and radians. The package is filled in by the grinding issue;
it ships empty so the layout (tipgeo, cam, gcode) is in place.
"""

__all__: list[str] = []
