"""Free-form non-rigid ICP (trimesh's Amberg) of the PPM template onto a prepared scan: the per-vertex fit the PPM
and its personal-detail layer are judged against (benchmarks/align_defects.py, the evaluation's nricp_hard).
Rigid ICP first, then the stiffness schedule that was best on defective scans. Millimetres, project frame; the
template's vertex order and faces are kept, so the result stitches like a PPM fit."""
from __future__ import annotations

import numpy as np
import trimesh

from ..template.register import NRICP_STEPS, register_onto

#: The schedule ending at stiffness 0.007 (three of NRICP_STEPS' four stages): the smallest distance to the clean
#: truth on the hardest defective scans of P039, P067 and P143 among the five tried (benchmarks/align_defects.py).
NRICP_SCHEDULE = NRICP_STEPS[:3]


def nricp_fit(template: trimesh.Trimesh, scan: trimesh.Trimesh,
              steps: tuple[tuple[float, float, float, int], ...] = NRICP_SCHEDULE) -> np.ndarray:
    """(n, 3) vertices (mm) of ``template`` moved rigidly, then non-rigidly onto the surface ``scan``."""
    return register_onto(template, scan, steps)
