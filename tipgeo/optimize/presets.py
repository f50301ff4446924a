"""Built-in study configs (the ``samples/`` folder holds them as TOML too; a
test keeps both in step).

Units: see :mod:`tipgeo.optimize.config` (variables in their spec keys' units).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import SpecError

if TYPE_CHECKING:
    from .config import StudyConfig

__all__ = ["STUDIES", "study_preset", "resolve_study", "HELICAL_STUDY_TOML",
           "BEVEL_STUDY_TOML"]

#: The thesis's 25-point helical study (§3.4.2), as ``samples/helical-study.toml``.
HELICAL_STUDY_TOML = """\
# tipgeo study — the thesis's GP optimisation of the helical needle (§3.4.2),
# over the whole design space a designer needs: ψ 5–25°, φ 5–20°.
# The base is the calibrated thesis needle (helical-14G: p_h = 100 mm, rulings
# normal to the cone opening towards +z_h, the needle leaning towards the
# helix axis, axis offset 4.7665 mm; see `tipgeo calibrate`). ψ and φ change as
# a CAD user changes them in that model: the rulings follow ψ, the needle
# tilts by φ about the point where its axis crosses the helicoid, and the rest
# of the placement is held. 25 training points like the thesis, all of them
# buildable (a maximin design over the admissible part of the box); for more,
# raise [design] points.
#
#   tipgeo sweep samples/helical-study.toml
#   tipgeo optimize samples/helical-study.toml --out helical-study
#
# Units: variables in their spec keys' units (degrees here); responses carry
# theirs in their names (mm, deg).
name = "helical-study"
description = "thesis §3.4.2: GP of l_c, λ, θ, α over ψ 5–25° and φ 5–20°; Table 3.4 objectives"
base = "helical-14G"

# Beyond φ ≈ 16° the calibrated needle leans so far towards the helix axis
# that the helicoid folds over inside the tube (or its mesh at the default
# tolerance would exceed the cap of tol.helical_max_grid): such points are
# refused at validation with that reason. The design screens its candidates
# so and reports the refused share of the box.
[[variables]]
name = "psi_deg"
path = "cutters[0].helix_angle_deg"
min = 5.0
max = 25.0

[[variables]]
name = "phi_deg"
path = "cutters[0].phi_deg"
min = 5.0
max = 20.0

# maximin: 25 points chosen among the candidates of a 21 × 21 grid over the box
# that pass validation, spread so that the closest two are as far apart as
# possible (on the unit box); seeded, deterministic (tipgeo/optimize/design.py).
# A 5 × 5 grid (method = "grid", levels = 5) would waste 7 of its 25 points
# on refused configurations.
[design]
method = "maximin"
points = 25
seed = 0

[analysis]
method = "exact"
responses = ["l_c_mm", "lambda_min_deg", "lambda_max_deg", "theta_min_deg",
             "theta_max_deg", "alpha_min_deg", "alpha_max_deg"]

[sweep]
workers = 2
cache = true

[surrogate]
# the thesis's GP models all seven outputs (without this line, only the three
# the objectives use would be fitted)
responses = ["l_c_mm", "lambda_min_deg", "lambda_max_deg", "theta_min_deg",
             "theta_max_deg", "alpha_min_deg", "alpha_max_deg"]
nugget = false
mode = "independent"
# Matérn 5/2, not the thesis's Gaussian (eq. 3.26): the min/max-over-the-edge
# responses have kinks, and on 250 held-out 1° grid points (trained on the
# earlier 5 × 5 grid) the Gaussian's 95 % intervals held 56–80 % of them, the
# Matérn 5/2's 90–98 % (README).
kernel = "matern52"
# θ_max (the edge's largest θ, near the heel) has no kink: its likelihood
# (eq. 3.30, on these 25 points) prefers the smoother Matérn 7/2 decisively
# (L = −176.9 against −148.2 for 5/2; for the kinked responses the two are
# within 0.5–1.7 of each other). With 5/2 its LOO intervals held all 25
# points and 98.8 % of 242 held-out ones (too wide); with 7/2, 23/25 and a
# mean 5× closer (README).
response_kernels = { theta_max_deg = "matern72" }
starts = 12
seed = 0
calibrate = false     # true: σ̂ scaled so the LOO 95 % intervals hold ~95 % by construction

# Each optimum is built and analysed for real; while the GP misses any of the
# objectives' responses there by more than 1 % of its training range, that
# point joins the training set and the GP is re-fitted (at most 8 rounds).
[infill]
rounds = 8
threshold = 0.01

[[objectives]]
name = "min-theta-max-lambda"
terms = [{ response = "theta_min_deg", goal = "min" },
         { response = "lambda_max_deg", goal = "max" }]

[[objectives]]
name = "min-lc-max-lambda"
terms = [{ response = "l_c_mm", goal = "min" },
         { response = "lambda_max_deg", goal = "max" }]

[[objectives]]
name = "min-lc-min-theta"
terms = [{ response = "l_c_mm", goal = "min" },
         { response = "theta_min_deg", goal = "min" }]

[plots]
responses = ["l_c_mm", "lambda_max_deg", "theta_min_deg"]   # Fig. 3.17: (a) l_c, (b) λ_max
variables = ["psi_deg", "phi_deg"]
"""

#: A one-plane bevel over the thesis's bevel angles, as ``samples/bevel-study.toml``:
#: the study with closed forms (θ_min = ξ, λ_max = 90° − ξ, l_c an ellipse's
#: perimeter) and two responses constant over the box (λ_min = α_min = 0).
BEVEL_STUDY_TOML = """\
# tipgeo study — the one-plane bevel (thesis §2.1.1, §2.4.1) over the thesis's
# bevel angles ξ = 15–75° (its needles: 15°, 45°, 75°), with the objectives of
# Table 3.4. A bevel is the case with closed forms to check the optimiser on:
# θ_min = ξ (at the tip), λ_max = 90° − ξ and α_max = 90° − ξ (at γ = ±90°),
# l_c the perimeter of the ellipse of semi-axes r_o/sin ξ and r_o; λ_min and
# α_min are 0 whatever ξ (constant: not fitted, listed in the report).
#
#   tipgeo sweep samples/bevel-study.toml
#   tipgeo optimize samples/bevel-study.toml --out bevel-study   # or the built-in bevel-study
#
# Units: the variable in its spec key's unit (degrees); responses carry theirs
# in their names (mm, deg).
name = "bevel-study"
description = "one-plane bevel: GP of l_c, λ_max, θ_min over ξ 15–75°; Table 3.4 objectives"
base = "bevel-14G-xi15"

[[variables]]
name = "xi_deg"
path = "cutters[0].xi_deg"
min = 15.0
max = 75.0

# 13 training points, every 5° (a bevel's analysis takes ~0.1 s). l_c grows
# like 1/sin ξ towards 15°: with 7 points (every 10°) its GP missed the
# closed form by up to 4.6 % of its range between them, with 13 by 0.7 %.
[design]
method = "grid"
levels = 13

# the seven outputs of §3.4.2 are recorded; GPs are fitted to those the
# objectives use (l_c, λ_max, θ_min)
[analysis]
method = "exact"

[sweep]
workers = 1
cache = true

# Matérn 5/2: on 601 points between the 13 its 95 % intervals held 89 % of
# the closed-form l_c (the Gaussian's 15 %, too sure of itself)
[surrogate]
mode = "independent"
kernel = "matern52"
starts = 6
seed = 0

[infill]
rounds = 8
threshold = 0.01

# θ_min and λ_max both favour a small ξ: the first optimum sits on ξ = 15°.
[[objectives]]
name = "min-theta-max-lambda"
terms = [{ response = "theta_min_deg", goal = "min" },
         { response = "lambda_max_deg", goal = "max" }]

# l_c falls as ξ grows, λ_max too: a compromise inside the box.
[[objectives]]
name = "min-lc-max-lambda"
terms = [{ response = "l_c_mm", goal = "min" },
         { response = "lambda_max_deg", goal = "max" }]

# the same conflict as a Pareto front (every ξ is on it), its point nearest
# the ideal as the compromise
[[objectives]]
name = "min-lc-min-theta"
combine = "pareto"
terms = [{ response = "l_c_mm", goal = "min" },
         { response = "theta_min_deg", goal = "min" }]
"""

#: name -> TOML text
STUDIES = {"helical-study": HELICAL_STUDY_TOML, "bevel-study": BEVEL_STUDY_TOML}


def study_preset(name: str) -> StudyConfig:
    """The built-in study ``name`` as a :class:`~tipgeo.optimize.config.StudyConfig`."""
    from .config import loads_config

    if name not in STUDIES:
        raise SpecError(f"study = {name!r} is not a built-in study; allowed: "
                        + ", ".join(STUDIES))
    return loads_config(STUDIES[name])


def resolve_study(arg: str | Path | StudyConfig) -> StudyConfig:
    """A study config from what a user typed: a StudyConfig as it is, a study
    file (``.toml``, or any existing file) or a built-in study name.

    Raises :class:`~tipgeo.errors.SpecError` naming ``arg`` and the built-in
    studies when it is none of these.
    """
    from ..tomlio import resolve_file_or_name
    from .config import StudyConfig, load_config

    config: StudyConfig = resolve_file_or_name(  # type: ignore[no-untyped-call,unused-ignore]  # tomlio: typed by its owner
        arg, kind=StudyConfig, load=load_config, named=study_preset, names=STUDIES,
        what="CONFIG", file_word="study file (.toml)", named_as="built-in study",
        listing="built-in")
    return config
