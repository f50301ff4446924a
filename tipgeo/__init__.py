"""tipgeo — geometry and CAM of hollow-needle tips."""
