"""Shared fixtures: paths to the real data in ../shared/data and one rigged PPM per test session.

bpy is imported before pymeshlab in this process (pymeshlab ships an older Embree).
"""
from __future__ import annotations

from pathlib import Path

import bpy  # noqa: F401  (must come before pymeshlab)
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"
SONICOM = SHARED_DATA / "sonicom"


@pytest.fixture(scope="session")
def sonicom() -> Path:
    if not SONICOM.is_dir():
        pytest.fail(f"{SONICOM} is missing: the tests need ../shared/data beside the checkout")
    return SONICOM


@pytest.fixture(scope="session")
def model():
    """The packaged template rigged in Blender (built once; tests reset its parameters)."""
    from ppm.model import PinnaModel
    from ppm.parameters import PinnaParameters

    pinna = PinnaModel.from_template()
    yield pinna
    pinna.set_parameters(PinnaParameters.default())


@pytest.fixture(scope="session")
def p143_both_ears(sonicom):
    """SONICOM P143's closed head with both ears finely resolved (listener.dataset_heads.both_ears_head; mm,
    the dataset's frame), built once for every test that needs it."""
    from listener.dataset_heads import both_ears_head

    return both_ears_head(sonicom / "P143")


@pytest.fixture()
def rng() -> np.random.Generator:
    return np.random.default_rng(20261123)
