"""Test configuration: strict invariant checks on, shared built tips."""

import functools

import pytest

from tipgeo import build_tip, preset
from tipgeo.tolerances import tol

tol.strict = True


@functools.cache
def built(name: str):
    """Build a preset once per session (tips are not mutated by tests)."""
    return build_tip(preset(name))


@pytest.fixture(scope="session")
def build_preset():
    return built
