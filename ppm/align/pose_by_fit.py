"""The pose of a scan decided by the PPM itself: the PPM is fitted in the best rigid pose found by
:func:`ppm.align.any_pose.find_pose` and in every alternative kept there, and the fit nearest the scan wins when
it clearly beats the fits that land elsewhere (millimetres, project frame: x front, y left, z up).

Above :mod:`ppm.align.any_pose` (the rigid pose) and :mod:`ppm.align.fit` (the PPM fit), so that neither of
those imports the other.
"""
from __future__ import annotations

import dataclasses
import logging

import numpy as np
import trimesh

from .any_pose import FIT_AMBIGUITY_RATIO, SAME_FIT_MM, PoseUncertainError, side_name
from .fit import align
from .pose import apply_similarity
from .report import one_sided_distances_mm
from .target import target_from_mesh

log = logging.getLogger(__name__)


def pose_summary(target) -> dict:
    """What an alignment summary records of a target prepared in any pose (empty for a project-frame scan):
    the (4, 4) similarity scan -> project frame, the unit and whether the scan was a right ear."""
    if target.pose is None:
        return {}
    return {"scan_to_project": target.pose["matrix"], "mirrored": target.pose["mirrored"], "unit": target.pose["unit"]}


def target_in_alternative_pose(target, alternative: dict):
    """The prepared target (project frame by its best rigid pose) moved into an alternative pose of
    ``target.pose['alternatives']``; its ``pose`` then describes that alternative."""
    relative = np.asarray(alternative["matrix"]) @ np.linalg.inv(np.asarray(target.pose["matrix"]))
    moved = target_from_mesh(apply_similarity(target.mesh, relative), target.source)
    pose = {**target.pose, "matrix": alternative["matrix"], "mirrored": alternative["mirrored"], "alternatives": []}
    scan = None if target.scan is None else apply_similarity(target.scan, relative)
    return dataclasses.replace(moved, warnings=target.warnings, pose=pose, scan=scan)


def align_any_pose(model, target, settings=None):
    """Fit the PPM to a target prepared with scan_pose 'any': in its best rigid pose and in every alternative
    kept by :func:`find_pose`; the fit with the smallest median scan-to-model distance wins when it beats the
    others by FIT_AMBIGUITY_RATIO. Returns (alignment result, the target in the chosen pose). A target without
    alternatives is fitted once.

    Raises
    ------
    PoseUncertainError
        If two poses' PPM fits are about equally good.
    """
    options = [target] + [target_in_alternative_pose(target, alternative)
                          for alternative in (target.pose or {}).get("alternatives", [])]
    fits = []
    for option in options:
        result = align(model, option, settings)
        median = float(np.median(one_sided_distances_mm(option, result.vertices_mm, model.faces)))
        log.info("%s: PPM fit as %s: median %.3f mm", target.source,
                 side_name(bool(option.pose and option.pose["mirrored"])), median)
        fits.append((median, result, option))
    fits.sort(key=lambda fit: fit[0])
    # competitors are fits that land somewhere else on the scan; two rotations that converge to the same
    # surface are one answer
    best_median, best_result, best_option = fits[0]
    to_best = np.asarray(best_option.pose["matrix"]) if best_option.pose else np.eye(4)
    best_surface = trimesh.Trimesh(best_result.vertices_mm, model.faces, process=False)
    competitors = []
    for median, result, option in fits[1:]:
        relative = to_best @ np.linalg.inv(np.asarray(option.pose["matrix"]))
        moved = trimesh.transform_points(result.vertices_mm, relative)
        if float(np.median(trimesh.proximity.closest_point(best_surface, moved)[1])) > SAME_FIT_MM:
            competitors.append((median, option))
    if competitors and competitors[0][0] < FIT_AMBIGUITY_RATIO * best_median:
        describe = ", ".join(f"{median:.3f} mm as {side_name(option.pose['mirrored'])}"
                             for median, option in [(best_median, best_option), *competitors])
        raise PoseUncertainError(
            f"{target.source}: the PPM fits the scan about equally well in different poses (median distance "
            f"{describe}): the scan shows too little of the pinna's shape to orient it. Give it in the project "
            "frame (x front, y left, z up, mm) instead")
    if competitors:
        best_result.warnings.append(f"pose decided by the PPM fit: median {best_median:.3f} mm against "
                                    f"{competitors[0][0]:.3f} mm in the next pose")
    return best_result, best_option
