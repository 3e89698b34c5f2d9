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


def _local_quadrics(points_mm: np.ndarray, neighbours: int,
                    reference_mm: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Per point, its height (mm) over the quadric z = ax² + bxy + cy² + dx + ey + f fitted by least squares to its
    ``neighbours`` nearest points of ``reference_mm`` (the points themselves where None; the point itself left out),
    in the frame of their principal axes (z: the least one), and that z axis (unit)."""
    points = np.asarray(points_mm, dtype=np.float64)
    reference = points if reference_mm is None else np.asarray(reference_mm, dtype=np.float64)
    if len(reference) <= neighbours:
        raise PpmError(f"a scan of {len(reference)} points is too small to judge its noise "
                       f"(needs more than {neighbours})")
    if not (np.isfinite(points).all() and np.isfinite(reference).all()):
        raise PpmError("the scan's points hold NaN or infinite coordinates; clean the file before judging its noise")
    distance, index = cKDTree(reference).query(points, neighbours + 1)
    # leave the point itself out where it is among the reference (at distance 0), else the farthest of the k + 1
    itself = distance[:, 0] == 0.0
    index = np.where(itself[:, None], index[:, 1:], index[:, :-1])
    offsets = reference[index] - points[:, None, :]  # (n, k, 3): the neighbours about the point
    centred = offsets - offsets.mean(axis=1, keepdims=True)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)  # (n, 3, 3): rows are the principal axes
    local = np.einsum("nkj,nij->nki", offsets, axes)
    x, y, z = local[..., 0], local[..., 1], local[..., 2]
    design = np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=-1)  # (n, k, 6)
    normal = np.einsum("nki,nkj->nij", design, design) + 1e-9 * np.eye(6)
    right = np.einsum("nki,nk->ni", design, z)
    coefficients = np.linalg.solve(normal, right[..., None])[..., 0]
    return -coefficients[:, 5], axes[:, 2]  # the point sits at the frame's origin: its height is 0 - f


def local_heights_mm(points_mm: np.ndarray, neighbours: int = NEIGHBOURS,
                     reference_mm: np.ndarray | None = None) -> np.ndarray:
    """Per point (mm), its height over the quadric z = ax² + bxy + cy² + dx + ey + f fitted by least squares to its
    ``neighbours`` nearest points (itself left out), in the frame of their principal axes (z: the least one). The
    neighbours are taken from ``reference_mm`` where given (a subset of the points, e.g. without the strays), else
    from the points themselves."""
    return _local_quadrics(points_mm, neighbours, reference_mm)[0]


def scan_noise_mm(points_mm: np.ndarray, neighbours: int = NEIGHBOURS) -> float:
    """The scan's noise (mm, a standard deviation) from its points (``points_mm``: (n, 3), mm): robust spread of
    :func:`local_heights_mm`, widened by the leave-one-out fit's own uncertainty (six parameters, ``neighbours``
    points)."""
    heights = local_heights_mm(points_mm, neighbours)
    return float(1.4826 * np.median(np.abs(heights)) / np.sqrt(1.0 + 6.0 / neighbours))


def stray_points(points_mm: np.ndarray, sigmas: float, floor_mm: float, noise_mm: float | None = None,
                 neighbours: int = NEIGHBOURS) -> np.ndarray:
    """Which points (bool, (n,)) stand off the scan's local surface by more than ``sigmas`` x the scan's noise
    (``noise_mm``, else :func:`scan_noise_mm`; not below ``floor_mm``, so that on a clean scan only what lies well
    off the surface counts): outliers near the surface, which an isolation test keeps (a point thrown 2-3 mm off a
    scan sampled every 2 mm still has neighbours). Two passes: the heights over quadrics through all neighbours, then
    over quadrics through the neighbours the first pass kept, so that a good point beside an outlier is not taken
    for one."""
    points = np.asarray(points_mm, dtype=np.float64)
    noise = scan_noise_mm(points, neighbours) if noise_mm is None else float(noise_mm)
    limit = sigmas * max(noise, floor_mm)
    first = np.abs(local_heights_mm(points, neighbours)) > limit
    if not first.any() or (~first).sum() <= neighbours:
        return first
    return np.abs(local_heights_mm(points, neighbours, reference_mm=points[~first])) > limit


def settle_strays(points_mm: np.ndarray, stray: np.ndarray, neighbours: int = NEIGHBOURS) -> np.ndarray:
    """The points (mm) with each stray one (``stray``: bool, from :func:`stray_points`) moved onto the quadric through
    its nearest points that are not strays, along that quadric's axis: the scan keeps its faces and its sampling, but a
    point thrown off the surface no longer lifts a tent of faces off it."""
    points = np.array(points_mm, dtype=np.float64)
    if not stray.any():
        return points
    heights, axes = _local_quadrics(points[stray], neighbours, points[~stray])
    points[stray] -= heights[:, None] * axes
    return points
