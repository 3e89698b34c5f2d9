"""A separate, better scan of one ear registered onto the head's ear, so that the PPM is fitted to it where the
ear sits on the head.

The scan (PLY/STL/OBJ, any pose and offset, mm/cm/m) is of the same ear as the head's crop, so a rigid registration
suffices: starts from the principal axes of both (every proper sign combination) and spins about the scan's
mean normal, each refined by ICP of the scan onto the crop (trimesh), scored by the median distance of the scan's
points to the crop's surface over the middle 80 % (a scan may hold more or less skin than the crop). The best must
come within ``MAX_MEDIAN_MM``, or the scan is refused: it is not this head's ear (or not an ear).

Where the ear scans share the head scan's coordinates and unit (one scanning session; config listeners:
``ear_scan_frame: head``), :func:`place_ear_scan` moves them by the head's own frame instead and only checks that they
lie on the head's ear. A defective scan does not pin its pose down: registered, the hard scans of P143's and P067's
ears (0.5 mm noise, 2 mm sampling, holes) land 0.24-0.58 mm (median over their vertices) from their place, and on
P143's right one a pose 0.35 mm off fits the head's ear better, by a robust point-to-plane score, than the true pose
(benchmarks/ear_scan_placement.py); placing such a scan by the head's frame costs nothing of that.

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
    median, near = _on_ear(moving[::4] @ matrix[:3, :3].T + matrix[:3, 3], crop, side, source,
                           "does not register onto")
    registered = trimesh.Trimesh(np.asarray(scan_mm.vertices) @ matrix[:3, :3].T + matrix[:3, 3], scan.faces,
                                 process=False)
    return registered, {"unit": unit, "median_mm": round(median, 3), "share_within_1mm": round(near, 3), "side": side,
                        "placed_by": "registration"}


def _on_ear(points_mm: np.ndarray, crop: trimesh.Trimesh, side: str, source: str, verb: str,
            advice: str = "") -> tuple[float, float]:
    """(trimmed median distance mm, share within NEAR_MM) of the scan's points to the head's ear; raises
    ListenerError where they are too far for the scan to be this ear where it is (``advice`` ends its message)."""
    _, distance, _ = trimesh.proximity.closest_point(crop, points_mm)
    median, near = _trimmed_median(distance), float(np.mean(distance < NEAR_MM))
    if median > MAX_MEDIAN_MM or near < MIN_NEAR_SHARE:
        raise ListenerError(f"{source}: the {side} ear scan {verb} the head's {side} ear (median distance {median:.2f} "
                            f"mm, at most {MAX_MEDIAN_MM:g}; {100 * near:.0f} % of it within {NEAR_MM:g} mm, at least "
                            f"{100 * MIN_NEAR_SHARE:.0f} %); is it this listener's {side} ear, and an ear at all?{advice}")
    return median, near


def place_ear_scan(scan: trimesh.Trimesh, head_matrix: np.ndarray, head_unit: str, crop: trimesh.Trimesh, side: str,
                   source: str = "ear scan") -> tuple[trimesh.Trimesh, dict]:
    """``scan``, given in the head scan's own coordinates and unit, moved into the project frame by the head's frame
    ``head_matrix`` (4x4, head scan coordinates -> project frame mm; ``frame.json``'s ``matrix``), and a summary
    like :func:`register_ear_scan`'s. No registration: the scan keeps the place the scanner gave it.

    Raises
    ------
    ListenerError
        If the scan's unit is not the head's, or it does not lie on the head's ``side`` ear (``crop``, mm) within
        ``MAX_MEDIAN_MM``: then it was not taken in the head scan's coordinates; leave ``ear_scan_frame`` out to have
        it registered.
    """
    try:
        unit, _ = detect_unit(np.asarray(scan.vertices), source)
    except PpmError as error:
        raise ListenerError(str(error)) from error
    if unit != head_unit:
        raise ListenerError(f"{source}: the {side} ear scan is in {unit} and the head scan in {head_unit}; with "
                            "ear_scan_frame: head both must share one unit and one set of coordinates (or leave "
                            "ear_scan_frame out to have the ear scan registered)")
    matrix = np.asarray(head_matrix, dtype=np.float64)
    vertices = np.asarray(scan.vertices, dtype=np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    placed = trimesh.Trimesh(vertices, scan.faces, process=False)
    points = placed.sample(POINTS, seed=1) if len(placed.faces) else vertices
    median, near = _on_ear(points, crop, side, source, "placed by the head's frame does not lie on",
                           " With ear_scan_frame: head the scan must share the head scan's coordinates; leave "
                           "ear_scan_frame out to have it registered.")
    return placed, {"unit": unit, "median_mm": round(median, 3), "share_within_1mm": round(near, 3), "side": side,
                    "placed_by": "head frame"}
