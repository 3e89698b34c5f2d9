"""How noisy a scan is: the spread of its points about a smooth local surface (millimetres).

Each point's height over a quadric fitted, in the local tangent frame, to its nearest neighbours without it; the
robust spread (1.4826 x the median absolute height, corrected for the quadric's six parameters) is the estimate.
Curvature the quadric cannot follow and coarse sampling add to it, so it reads a little high on a coarse scan (the
`hard` defect level, 0.5 mm of noise at 2 mm spacing, reads 0.60-0.64 mm); outliers and spikes barely move a median.
Used by the personal-detail layer (``ppm.align.detail``) to keep its field no more supple than the scan's noise
allows.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..errors import PpmError

#: Neighbours each point's quadric is fitted to.
NEIGHBOURS = 20


def local_heights_mm(points_mm: np.ndarray, neighbours: int = NEIGHBOURS) -> np.ndarray:
    """Per point (mm), its height over the quadric z = ax² + bxy + cy² + dx + ey + f fitted by least squares to its
    ``neighbours`` nearest points (itself left out), in the frame of their principal axes (z: the least one)."""
    points = np.asarray(points_mm, dtype=np.float64)
    if len(points) <= neighbours:
        raise PpmError(f"a scan of {len(points)} points is too small to judge its noise (needs more than {neighbours})")
    if not np.isfinite(points).all():
        raise PpmError("the scan's points hold NaN or infinite coordinates; clean the file before judging its noise")
    _, index = cKDTree(points).query(points, neighbours + 1)
    offsets = points[index[:, 1:]] - points[:, None, :]  # (n, k, 3): the neighbours about the point
    centred = offsets - offsets.mean(axis=1, keepdims=True)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)  # (n, 3, 3): rows are the principal axes
    local = np.einsum("nkj,nij->nki", offsets, axes)
    x, y, z = local[..., 0], local[..., 1], local[..., 2]
    design = np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=-1)  # (n, k, 6)
    normal = np.einsum("nki,nkj->nij", design, design) + 1e-9 * np.eye(6)
    right = np.einsum("nki,nk->ni", design, z)
    coefficients = np.linalg.solve(normal, right[..., None])[..., 0]
    return -coefficients[:, 5]  # the point sits at the frame's origin: its height is 0 - f


def scan_noise_mm(points_mm: np.ndarray, neighbours: int = NEIGHBOURS) -> float:
    """The scan's noise (mm, a standard deviation) from its points (``points_mm``: (n, 3), mm): robust spread of
    :func:`local_heights_mm`, widened by the leave-one-out fit's own uncertainty (six parameters, ``neighbours``
    points)."""
    heights = local_heights_mm(points_mm, neighbours)
    return float(1.4826 * np.median(np.abs(heights)) / np.sqrt(1.0 + 6.0 / neighbours))
