"""The unit of a head scan (mm, cm or m), told from its size: a head is 150-360 mm across.

The size is the diameter of the sphere with the volume of the scan's convex hull, which an open scan has too.
Inches are refused (a head in inches is 5.9-14.2 units across, between metres and centimetres).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from .errors import ListenerError

#: Millimetres per unit.
UNIT_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0}
INCH_MM = 25.4


def head_diameter(vertices: np.ndarray) -> float:
    """Diameter (in the file's units) of the sphere with the volume of the convex hull of ``vertices``."""
    volume = ConvexHull(np.asarray(vertices, dtype=np.float64)).volume
    return float((6.0 * volume / np.pi) ** (1.0 / 3.0))


def infer_unit(vertices: np.ndarray, diameter_range_mm: tuple[float, float], source: str = "head mesh") -> str:
    """'mm', 'cm' or 'm': the unit in which ``vertices`` make a head ``diameter_range_mm`` across.

    Raises
    ------
    ListenerError
        If the scan is in inches, or no unit makes it head-sized.
    """
    low, high = diameter_range_mm
    diameter = head_diameter(vertices)
    for unit, factor in UNIT_MM.items():
        if low <= diameter * factor <= high:
            return unit
    if low <= diameter * INCH_MM <= high:
        raise ListenerError(f"{source}: the head is {diameter:.3g} units across, which is a head in inches "
                            f"({diameter * INCH_MM:.0f} mm); export it in millimetres (or scale it by {INCH_MM})")
    raise ListenerError(f"{source}: the head is {diameter:.4g} units across; no unit of mm, cm or m makes that a "
                        f"head ({low:.0f}-{high:.0f} mm): check that the file is a whole head scan and its units")
