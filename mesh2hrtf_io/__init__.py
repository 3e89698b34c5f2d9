"""Mesh2HRTF project export (NumCalc input) from head meshes in millimetres; metres inside projects.

The names below are imported on first use, so that a part that needs no mesh library (the GPU solver's
:mod:`mesh2hrtf_io.bem_arrays`, on a machine with only NumPy, SciPy and CuPy) imports without trimesh.
"""
from __future__ import annotations

import importlib

from .errors import Mesh2HrtfIoError

_EXPORTS = {"check_mesh": ".checks", "mesh_problems": ".checks", "EvaluationGrid": ".grids",
            "grid_from_sofa": ".grids", "ring_grid": ".grids", "sagittal_grid": ".grids", "sphere_grid": ".grids",
            "ProjectLayout": ".project", "write_project": ".project"}

__all__ = sorted([*_EXPORTS, "Mesh2HrtfIoError"])


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
