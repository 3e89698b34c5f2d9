"""Fitting again on more of the scan when the pinna segmentation left part of the pinna out (mm, project frame).

The segmented target (``ppm.template.segment``) holds the thin flap a ray crosses; on a scan that saw the ear from
the side only, the lobule and other single-faced parts fail that test and are cut away with the head skin, so the fit
never sees them. Once the PPM is fitted, it says where the pinna is: the scan's points within ``reach_mm`` of the
fitted surface are the pinna and its skin (nothing the fit's trimmed cost would not count anyway). Those the target
left out and whose closest point on the fit lies more than ``pinna_from_rim_mm`` inside the PPM's open rim (over the
pinna, not the head skin beyond its ring) are the pinna the segmentation missed; when they are more than
``refit_above_share`` of the points around the fit, the PPM is fitted again on all of those. Settings in
``ppm/data/target_widening.yaml``, with what they were chosen on.
"""
from __future__ import annotations

import dataclasses
import logging
from importlib import resources

import numpy as np
import trimesh
import yaml
from scipy.spatial import cKDTree

from ..errors import PpmError
from ..geodesic import distance_from_rim_mm
from ..template.segment import crop_to_region
from .fit import AlignmentResult, AlignSettings, align
from .target import Target, target_from_mesh

log = logging.getLogger(__name__)

#: Two target points closer than this (mm) are the same scan vertex.
SAME_POINT_MM = 1e-6


@dataclasses.dataclass(frozen=True)
class WideningSettings:
    """When and how far to widen the target (``ppm/data/target_widening.yaml``); lengths in mm."""

    reach_mm: float
    pinna_from_rim_mm: float
    refit_above_share: float

    @classmethod
    def packaged(cls, **overrides) -> "WideningSettings":
        """The packaged settings, with ``overrides`` (unknown names raise, naming the data file)."""
        text = resources.files("ppm").joinpath("data/target_widening.yaml").read_text(encoding="utf-8")
        values = {**yaml.safe_load(text), **overrides}
        unknown = set(values) - {field.name for field in dataclasses.fields(cls)}
        if unknown:
            raise PpmError(f"ppm/data/target_widening.yaml: unknown settings {sorted(unknown)}")
        return cls(**{key: float(value) for key, value in values.items()})


def widened_target(target: Target, vertices_mm: np.ndarray, faces: np.ndarray, reach_mm: float) -> Target | None:
    """The scan's part within ``reach_mm`` of the fitted PPM (``vertices_mm``, ``faces``) as a target (outliers
    removed as in any target), or None when the target keeps no scan or too little of it lies there."""
    if target.scan is None or len(target.scan.faces) == 0:
        return None
    fitted = trimesh.Trimesh(np.asarray(vertices_mm), np.asarray(faces), process=False)
    distance = trimesh.proximity.closest_point(fitted, np.asarray(target.scan.vertices))[1]
    try:
        widened = target_from_mesh(crop_to_region(target.scan, distance <= reach_mm), target.source)
    except PpmError as error:
        log.warning("%s: no wider target (%s)", target.source, error)
        return None
    return dataclasses.replace(widened, warnings=target.warnings, pose=target.pose, scan=target.scan)


def left_out_share(target: Target, widened: Target, vertices_mm: np.ndarray, faces: np.ndarray,
                   pinna_from_rim_mm: float) -> float:
    """Share of the widened target's points that the segmented ``target`` does not hold and that lie over the
    fitted PPM's pinna: their closest point on it (``vertices_mm``, ``faces``) more than ``pinna_from_rim_mm`` from
    its open rim (the skin beyond the ring maps onto the rim itself)."""
    left_out = cKDTree(target.points_mm).query(widened.points_mm)[0] > SAME_POINT_MM
    fitted = trimesh.Trimesh(np.asarray(vertices_mm), np.asarray(faces), process=False)
    triangle = trimesh.proximity.closest_point(fitted, widened.points_mm)[2]
    from_rim = distance_from_rim_mm(vertices_mm, faces)[np.asarray(faces)[triangle]].min(axis=1)
    return float(np.mean(left_out & (from_rim > pinna_from_rim_mm)))


def refit_widened(model, target: Target, result: AlignmentResult, settings: AlignSettings | None = None,
                  widening: WideningSettings | None = None) -> tuple[AlignmentResult, Target, dict]:
    """After ``result`` (the PPM fitted to ``target``): the fit on the widened target when the segmentation left out
    more than the packaged share of it, else ``result`` itself. Returns (fit, the target it was fitted to, a
    summary for the fit's report: share left out, points before and after, whether it refitted)."""
    widening = widening or WideningSettings.packaged()
    widened = widened_target(target, result.vertices_mm, model.faces, widening.reach_mm)
    if widened is None:
        return result, target, {"refitted": False, "reason": "no whole scan kept with the target"}
    share = left_out_share(target, widened, result.vertices_mm, model.faces, widening.pinna_from_rim_mm)
    summary = {"left_out_share": round(share, 4), "target_points": int(len(target.points_mm)),
               "widened_points": int(len(widened.points_mm)), "reach_mm": widening.reach_mm,
               "pinna_from_rim_mm": widening.pinna_from_rim_mm, "refit_above_share": widening.refit_above_share,
               "refitted": share > widening.refit_above_share}
    if not summary["refitted"]:
        return result, target, summary
    log.info("%s: the segmentation left out pinna: %.0f %% of the scan around the fit; fitting again on %d points",
             target.source, 100 * share, len(widened.points_mm))
    refit = align(model, widened, settings)
    refit.warnings.append(f"fitted again on the scan within {widening.reach_mm:g} mm of the first fit: the pinna "
                          f"segmentation had left out pinna, {100 * share:.0f} % of the scan there (a part seen from "
                          "one side only, such as the lobule)")
    return refit, widened, summary
