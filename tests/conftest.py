"""Test configuration: strict invariant checks on, shared built tips."""

import functools
import os
import sys

import pytest
from hypothesis import settings

from tipgeo import build_tip, preset
from tipgeo.tolerances import tol

tol.strict = True

# The CLI and docs tests start tipgeo in hundreds of child processes: let
# them cache bytecode (an environment with PYTHONDONTWRITEBYTECODE set makes
# every child compile every module it imports, ~0.1 s of CPU each)
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
sys.dont_write_bytecode = False

# no wall clock in any test: hypothesis's per-example deadline (200 ms by
# default) fails a property test on a loaded machine, not on a wrong answer
settings.register_profile("tipgeo", deadline=None)
settings.load_profile("tipgeo")


@functools.cache
def built(name: str):
    """Build a preset once per session (tips are not mutated by tests)."""
    return build_tip(preset(name))


@pytest.fixture(scope="session")
def build_preset():
    return built
