"""Shared fixtures: paths to the real data in ../shared/data and one rigged PPM per test session.

bpy is imported before pymeshlab in this process (pymeshlab ships an older Embree).
"""
from __future__ import annotations

import json
from pathlib import Path

import bpy  # noqa: F401  (must come before pymeshlab)
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"
SONICOM = SHARED_DATA / "sonicom"
MODULE_SECONDS = Path(__file__).with_name("module_seconds.json")


def pytest_collection_modifyitems(items: list) -> None:
    """The longest test files first (seconds measured in module_seconds.json; unlisted files are short), each
    file's own order kept: pytest-xdist's loadfile hands files out in collection order, and a long file handed
    out last keeps one worker busy while the other idles."""
    seconds = json.loads(MODULE_SECONDS.read_text(encoding="utf-8"))["seconds"]
    items.sort(key=lambda item: -seconds.get(Path(str(item.fspath)).name, 0))  # a stable sort: each file's order kept


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
