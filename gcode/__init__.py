"""Aerotech A3200 (AeroBasic) laser G-code: emitter, parser, interpreter and
ablation simulator for micro-serrations (thesis chapter 5, Appendix C).

Units mm, machine frame documented per module. The package is filled in by
the G-code issue; it ships empty so the layout (tipgeo, cam, gcode) is in
place.
"""

__all__: list[str] = []
