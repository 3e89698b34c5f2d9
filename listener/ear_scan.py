"""A separate, better scan of one ear registered onto the head's ear, so that the PPM is fitted to it where the
ear sits on the head.

The scan (PLY/STL/OBJ, any pose and offset, mm/cm/m) is of the same ear as the head's crop, so a rigid registration
suffices: starts from the principal axes of both (every proper sign combination) and spins about the scan's
mean normal, each refined by ICP of the scan onto the crop (trimesh), scored by the median distance of the scan's
points to the crop's surface over the middle 80 % (a scan may hold more or less skin than the crop). The best must
come within ``MAX_MEDIAN_MM``, or the scan is refused: it is not this head's ear (or not an ear).

Millimetres, project frame (x front, y left, z up); the ear stays on its own side.
"""
from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation
from trimesh.registration import icp

from ppm.align.any_pose import detect_unit
from ppm.errors import PpmError

from .errors import ListenerError

#: The registered scan's median distance to the head's ear (mm) at most; the same ear scanned twice is within a
#: fraction of a millimetre.
MAX_MEDIAN_MM = 1.0
#: ... and this share of its points within NEAR_MM of the head's ear at least (another person's ear, SONICOM
#: P039's on P143's head: 1.09 mm median).
NEAR_MM, MIN_NEAR_SHARE = 1.0, 0.7
#: Spins about the scan's mean normal tried from each start (deg).
SPIN_DEG = 30.0
#: Points of each surface used for the registration.
POINTS = 4000


def _principal_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    centre = points.mean(axis=0)
    _, _, axes = np.linalg.svd(points - centre, full_matrices=False)
    if np.linalg.det(axes) < 0:
        axes[2] = -axes[2]
    return centre, axes


def _trimmed_median(distance: np.ndarray) -> float:
    kept = np.sort(distance)[int(0.1 * len(distance)):int(0.9 * len(distance))]
    return float(np.median(kept))


def register_ear_scan(scan: trimesh.Trimesh, crop: trimesh.Trimesh, side: str,
                      source: str = "ear scan") -> tuple[trimesh.Trimesh, dict]:
    """``scan`` moved (and scaled to mm) onto ``crop`` (the head's ``side`` ear, mm, project frame), and a summary
    (unit, median distance mm, rotation of the best start).

    Raises
    ------
    ListenerError
        If no pose brings the scan within ``MAX_MEDIAN_MM`` of the head's ear.
    """
    try:
        unit, mm_per_unit = detect_unit(np.asarray(scan.vertices), source)
    except PpmError as error:
        raise ListenerError(str(error)) from error
    scan_mm = trimesh.Trimesh(np.asarray(scan.vertices) * mm_per_unit, scan.faces, process=False)
    rng = np.random.default_rng(0)
    moving = scan_mm.sample(POINTS, seed=1) if len(scan_mm.faces) else np.asarray(scan_mm.vertices)
    fixed = crop.sample(POINTS * 2, seed=2)
    tree = cKDTree(fixed)
    scan_centre, scan_axes = _principal_frame(moving)
    crop_centre, crop_axes = _principal_frame(fixed)
    best = None
    signs = [np.diag(s) for s in ([1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1])]
    for sign in signs:
        base = crop_axes.T @ sign @ scan_axes  # scan's principal axes onto the crop's
        normal = crop_axes[2]
        for spin in np.arange(0.0, 360.0, SPIN_DEG):
            rotation = Rotation.from_rotvec(np.radians(spin) * normal).as_matrix() @ base
            start = np.eye(4)
            start[:3, :3] = rotation
            start[:3, 3] = crop_centre - rotation @ scan_centre
            matrix, moved, _ = icp(moving[rng.choice(len(moving), 1000, replace=False)], fixed, initial=start,
                                   max_iterations=30, threshold=1e-5)
            score = _trimmed_median(tree.query(moving @ matrix[:3, :3].T + matrix[:3, 3])[0])
            if best is None or score < best[0]:
                best = (score, matrix)
    matrix, _, _ = icp(moving, fixed, initial=best[1], max_iterations=100, threshold=1e-6)
    _, distance, _ = trimesh.proximity.closest_point(crop, moving[::4] @ matrix[:3, :3].T + matrix[:3, 3])
    median, near = _trimmed_median(distance), float(np.mean(distance < NEAR_MM))
    if median > MAX_MEDIAN_MM or near < MIN_NEAR_SHARE:
        raise ListenerError(f"{source}: the {side} ear scan does not register onto the head's {side} ear (best median "
                            f"distance {median:.2f} mm, at most {MAX_MEDIAN_MM:g}; {100 * near:.0f} % of it within "
                            f"{NEAR_MM:g} mm, at least {100 * MIN_NEAR_SHARE:.0f} %); is it this listener's {side} ear, "
                            "and an ear at all?")
    registered = trimesh.Trimesh(np.asarray(scan_mm.vertices) @ matrix[:3, :3].T + matrix[:3, 3], scan.faces,
                                 process=False)
    return registered, {"unit": unit, "median_mm": round(median, 3), "share_within_1mm": round(near, 3), "side": side}
