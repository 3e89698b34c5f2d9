"""A scan in any pose, offset and unit brought into the project frame (millimetres, left ear), or a clear
report of why that is not possible.

1. Unit: the scan's bounding-box diagonal is compared with a pinna crop's (CROP_DIAGONAL_MM, under a factor
   of ten wide) for millimetres, centimetres and metres; exactly one fits. (Inches, 2.54 cm, cannot be told
   from centimetres by size: such scans must be given in millimetres.)
2. Pose: starts from the scan's area-weighted mean normal (the side the pinna faces) and its principal
   axes, both signs of the normal, spins about it every SPIN_DEG, and the mirror images of all of these
   (a right ear); each start is refined by rigid ICP of the template onto the scan (trimesh) and scored by
   the template's trimmed squared distance to the scan, a template vertex counting as unmatched where the
   scan's normal there faces the other way.
3. Verdict: the rigid template is a different ear, so a mirror image or a turned-over pose can fit it nearly as
   well (the rigid scores of the left and the mirrored answer differ by only 1.3-1.7x on the hardest defect
   level). Every other answer (other side, or a rotation more than DISTINCT_DEG away) within RESOLVE_RATIO of
   the best is kept, and :func:`ppm.align.pose_by_fit.align_any_pose` fits the PPM, a model of left ears, in each: the fit with the
   smallest median scan-to-model distance wins if it beats the fits that land elsewhere (more than SAME_FIT_MM
   away) by FIT_AMBIGUITY_RATIO. Otherwise, or
   when no rigid pose brings the template within MAX_MEDIAN_MM (median) of the scan,
   :class:`PoseUncertainError` says which poses compete and how well, instead of a wrong fit with a
   good-looking distance.
"""
from __future__ import annotations

import dataclasses
import logging

import numpy as np
import trimesh
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation
from trimesh.registration import icp

from ..errors import PpmError

log = logging.getLogger(__name__)

#: file units per millimetre that are tried
UNITS = {"mm": 1.0, "cm": 0.1, "m": 0.001}
#: bounding-box diagonal of a pinna crop, from the pinna alone (~45 mm) to a crop with much head skin
CROP_DIAGONAL_MM = (35.0, 300.0)
SPIN_DEG = 30.0             # spins of the start about the scan's mean normal
TRIM_MM = 5.0               # template vertices farther than this from the scan count as unmatched
DISTINCT_DEG = 20.0         # poses further apart than this are different answers
RESOLVE_RATIO = 2.0         # other answers whose rigid score is within this factor of the best's are fitted too
MAX_ALTERNATIVES = 2        # ... at most this many
FIT_AMBIGUITY_RATIO = 1.1   # the chosen PPM fit's median distance must be this many times better than the others'
SAME_FIT_MM = 1.0           # PPM fits whose surfaces lie closer than this (median) are the same answer
MAX_MEDIAN_MM = 2.5         # median template -> scan distance of an acceptable rigid pose (holes do not count)
ICP_POINTS = 1200           # template vertices used by the ICP of every start


class PoseUncertainError(PpmError):
    """The scan's pose (or unit, or side) cannot be told with confidence; the message says why."""


@dataclasses.dataclass(frozen=True)
class PoseCandidate:
    """One refined start: (4, 4) similarity scan -> project frame (mm), its score (trimmed mean squared
    distance, mm^2), the median distance of the template's matched vertices (mm) and whether it mirrors
    the scan."""

    matrix: np.ndarray
    score_mm2: float
    median_mm: float
    mirrored: bool


@dataclasses.dataclass(frozen=True)
class ScanPose:
    """How a scan was brought into the project frame.

    matrix : (4, 4) similarity from the scan's frame and unit to the project frame in mm (a reflection when
        the scan is a right ear); apply it with :func:`ppm.align.pose.apply_similarity`.
    unit : the detected unit; mirrored : the scan was a right ear; median_mm : median distance of the
        template at this pose; runner_up_ratio : score of the best other answer over the best's (inf if none);
        alternatives : other answers (other side or rotation) within RESOLVE_RATIO of the best, for the PPM fit
        to decide (:func:`ppm.align.pose_by_fit.align_any_pose`).
    """

    matrix: np.ndarray
    unit: str
    mirrored: bool
    median_mm: float
    runner_up_ratio: float
    alternatives: tuple[PoseCandidate, ...]
    candidates: tuple[PoseCandidate, ...]

    def summary(self) -> dict:
        """JSON-ready description (for reports)."""
        return {"unit": self.unit, "mirrored": self.mirrored, "median_mm": round(self.median_mm, 3),
                "runner_up_ratio": round(min(self.runner_up_ratio, 1e6), 2), "starts": len(self.candidates),
                "alternatives": [{"matrix": c.matrix.round(9).tolist(), "mirrored": c.mirrored,
                                  "score_ratio": round(c.score_mm2 / max(self.candidates[0].score_mm2, 1e-12), 3)}
                                 for c in self.alternatives]}


def detect_unit(vertices: np.ndarray, source: str = "scan") -> tuple[str, float]:
    """(unit name, millimetres per file unit) for which the scan's extent is that of a pinna crop.

    Raises
    ------
    PoseUncertainError
        If no unit, or more than one, gives a plausible size.
    """
    extent = float(np.linalg.norm(np.ptp(np.asarray(vertices, np.float64), axis=0)))
    fits = [(name, 1.0 / per_mm) for name, per_mm in UNITS.items()
            if CROP_DIAGONAL_MM[0] <= extent / per_mm <= CROP_DIAGONAL_MM[1]]
    if len(fits) != 1:
        sizes = ", ".join(f"{extent / per_mm:.4g} mm if {name}" for name, per_mm in UNITS.items())
        raise PoseUncertainError(
            f"{source}: cannot tell the unit: the scan is {extent:.4g} units across ({sizes}); a pinna crop is "
            f"{CROP_DIAGONAL_MM[0]:g}-{CROP_DIAGONAL_MM[1]:g} mm across. Scale it to millimetres")
    return fits[0]


def _frame(vertices: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(3, 3) rows: two in-plane principal axes and the normal (right-handed)."""
    centred = vertices - vertices.mean(axis=0)
    in_plane = centred - np.outer(centred @ normal, normal)
    _, _, axes = np.linalg.svd(in_plane, full_matrices=False)
    first = axes[0] - (axes[0] @ normal) * normal
    first /= np.linalg.norm(first)
    return np.stack([first, np.cross(normal, first), normal])


def _rotation_starts(scan: trimesh.Trimesh, template: trimesh.Trimesh) -> list[np.ndarray]:
    """(3, 3) rotations scan -> template frame: scan normal onto the template's (both signs), spun."""
    t_normal = template.face_normals.T @ template.area_faces
    t_normal /= np.linalg.norm(t_normal)
    t_frame = _frame(template.vertices, t_normal)
    s_normal = scan.face_normals.T @ scan.area_faces
    s_normal /= max(np.linalg.norm(s_normal), 1e-12)
    starts = []
    for sign in (1.0, -1.0):
        s_frame = _frame(scan.vertices, sign * s_normal)
        base = t_frame.T @ s_frame  # maps the scan's frame rows onto the template's
        for spin in np.arange(0.0, 360.0, SPIN_DEG):
            starts.append(Rotation.from_rotvec(np.deg2rad(spin) * t_normal).as_matrix() @ base)
    return starts


def _score(template_mm: np.ndarray, template_normals: np.ndarray, tree: cKDTree, scan_normals: np.ndarray
           ) -> tuple[float, float]:
    """(trimmed mean squared distance in mm^2, median distance in mm of the matched vertices)."""
    distance, index = tree.query(template_mm)
    matched = (np.einsum("ij,ij->i", template_normals, scan_normals[index]) > 0.0) & (distance < TRIM_MM)
    trimmed = np.where(matched, distance, TRIM_MM)
    return float(np.mean(trimmed**2)), float(np.median(distance[matched])) if matched.any() else np.inf


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    relative = a[:3, :3] @ np.linalg.inv(b[:3, :3])
    relative /= np.cbrt(np.linalg.det(relative))  # similarity -> rotation (same handedness compared only)
    return float(np.rad2deg(np.arccos(np.clip((np.trace(relative) - 1.0) / 2.0, -1.0, 1.0))))


def find_pose(scan: trimesh.Trimesh, template: trimesh.Trimesh, source: str = "scan",
              icp_iterations: int = 30) -> ScanPose:
    """The similarity that brings `scan` (any pose, unit, side) onto the `template` (mm, project frame,
    left ear); see the module docstring.

    Raises
    ------
    PoseUncertainError
        If the unit is ambiguous or no pose brings the template within MAX_MEDIAN_MM of the scan.
    """
    unit, mm_per_unit = detect_unit(scan.vertices, source)
    pick = np.linspace(0, len(template.vertices) - 1, min(ICP_POINTS, len(template.vertices))).astype(int)
    template_points = template.vertices[pick]
    template_normals = np.asarray(template.vertex_normals)[pick]
    candidates: list[PoseCandidate] = []
    for mirrored in (False, True):
        linear = mm_per_unit * (np.diag([1.0, -1.0, 1.0]) if mirrored else np.eye(3))
        scan_mm = trimesh.Trimesh(scan.vertices @ linear.T, scan.faces[:, ::-1] if mirrored else scan.faces,
                                  process=False)
        tree = cKDTree(scan_mm.vertices)
        scan_normals = np.asarray(scan_mm.vertex_normals)
        for rotation in _rotation_starts(scan_mm, template):
            # the template moves onto the scan: start with the inverse rotation, centroids matched
            initial = np.eye(4)
            initial[:3, :3] = rotation.T
            initial[:3, 3] = scan_mm.vertices.mean(axis=0) - rotation.T @ template.vertices.mean(axis=0)
            matrix, moved, _ = icp(template_points, scan_mm.vertices, initial=initial, threshold=1e-5,
                                   max_iterations=icp_iterations, reflection=False, scale=False)
            score, median = _score(moved, template_normals @ matrix[:3, :3].T, tree, scan_normals)
            to_template = np.linalg.inv(matrix)
            scan_to_project = np.eye(4)
            scan_to_project[:3, :3] = to_template[:3, :3] @ linear
            scan_to_project[:3, 3] = to_template[:3, 3]
            candidates.append(PoseCandidate(scan_to_project, score, median, mirrored))
    candidates.sort(key=lambda c: c.score_mm2)
    best = candidates[0]
    # the best of every other basin (the other side, or a rotation more than DISTINCT_DEG away)
    basins: list[PoseCandidate] = [best]
    for candidate in candidates[1:]:
        if all(candidate.mirrored != kept.mirrored or _angle_deg(candidate.matrix, kept.matrix) > DISTINCT_DEG
               for kept in basins):
            basins.append(candidate)
    ratio = basins[1].score_mm2 / max(best.score_mm2, 1e-12) if len(basins) > 1 else np.inf
    alternatives = tuple(c for c in basins[1:] if c.score_mm2 < RESOLVE_RATIO * best.score_mm2)[:MAX_ALTERNATIVES]
    log.info("%s: unit %s, %s, median %.2f mm, next other pose %.2fx worse (%d kept for the PPM to decide)", source,
             unit, side_name(best.mirrored), best.median_mm, ratio, len(alternatives))
    if best.median_mm > MAX_MEDIAN_MM:
        raise PoseUncertainError(
            f"{source}: no pose of the template fits the scan (best median distance {best.median_mm:.2f} mm > "
            f"{MAX_MEDIAN_MM:g} mm, unit {unit}): is it a pinna crop? Give it in the project frame instead")
    return ScanPose(best.matrix, unit, best.mirrored, best.median_mm, ratio, alternatives, tuple(candidates))


def side_name(mirrored: bool) -> str:
    """How a pose's side is told to the user."""
    return "a right ear (mirrored)" if mirrored else "a left ear"
