"""What a listener's ear scan saw: per ear and anatomical region, the share of the fitted pinna's surface with a scan
point nearby, and plain advice where a region was not seen.

A face of the fitted PPM counts as seen when a point of the prepared scan (outliers removed) lies within
:data:`SEEN_MM` of its centre: the same figure as the evaluation's "seen by the hard scan" (a scan sampled at 2 mm
has a point that near wherever it saw the surface) and as the personal-detail layer's evidence fade, which keeps the
PPM's shape beyond it. Faces get the region of their nearest landmark on the fit (``reporting.pinna_regions``;
the skin ring beyond 8 mm of every landmark is "surroundings"). Where the scan saw little of a region the PPM's
template shape stands there: on the evaluation's defective scans that is where most of the miss lay (P067: 3.8 of
5.3 pp). Millimetres, the left-ear frame of the fits (a right ear mirrored).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .pinna_regions import OUTSIDE, label_points, landmark_regions
from .stitched_region import SEEN_MM  # a face is seen when a scan point lies this close to its centre (mm)
#: A region with less of its area seen than this gets advice to rescan it.
ADVICE_SHARE = 0.7


def pinna_coverage(vertices_mm: np.ndarray, faces: np.ndarray, scan_points_mm: np.ndarray,
                   positions_mm: dict[str, np.ndarray]) -> list[dict]:
    """Per region (data-file order, then the surroundings): its area (mm^2) on the fitted pinna and the share of it
    seen by the scan (0-1); a last row "whole pinna" over every region but the surroundings."""
    from scipy.spatial import cKDTree  # noqa: PLC0415

    vertices_mm, faces = np.asarray(vertices_mm, np.float64), np.asarray(faces, np.int64)
    corners = vertices_mm[faces]
    centres = corners.mean(axis=1)
    areas = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    seen = cKDTree(np.asarray(scan_points_mm, np.float64)).query(centres, distance_upper_bound=SEEN_MM)[0] <= SEEN_MM
    labels = label_points(centres, positions_mm)
    rows = []
    for region in [*landmark_regions(), OUTSIDE]:
        mine = labels == region
        if mine.any():
            rows.append({"region": region, "area_mm2": float(areas[mine].sum()),
                         "seen_share": float(areas[mine & seen].sum() / areas[mine].sum())})
    pinna = labels != OUTSIDE
    rows.append({"region": "whole pinna", "area_mm2": float(areas[pinna].sum()),
                 "seen_share": float(areas[pinna & seen].sum() / max(areas[pinna].sum(), 1e-12))})
    return rows


def coverage_advice(coverage: dict[str, list[dict]]) -> list[str]:
    """Plain advice per ear (``coverage``: side -> :func:`pinna_coverage` rows): "rescan the left cymba conchae
    (31 % of it seen)" for each region under :data:`ADVICE_SHARE`; one line saying so when every region was seen."""
    lines = []
    for side, rows in coverage.items():
        for row in rows:
            if row["region"] in (OUTSIDE, "whole pinna") or row["seen_share"] >= ADVICE_SHARE:
                continue
            lines.append(f"rescan the {side} {row['region']} ({100 * row['seen_share']:.0f} % of it seen): the PPM's "
                         "template shape stands where the scan saw nothing")
    return lines or [f"every region of both ears was seen (at least {100 * ADVICE_SHARE:.0f} % of its area)"]


def scan_distance_per_vertex(vertices_mm: np.ndarray, scan_points_mm: np.ndarray) -> np.ndarray:
    """Distance (mm) of every pinna vertex to the nearest scan point: the picture of what the scan saw."""
    from scipy.spatial import cKDTree  # noqa: PLC0415

    return cKDTree(np.asarray(scan_points_mm, np.float64)).query(np.asarray(vertices_mm, np.float64))[0]


def coverage_picture(vertices_mm: np.ndarray, faces: np.ndarray, scan_points_mm: np.ndarray,
                     path: str | os.PathLike, title: str) -> Path:
    """The fitted pinna coloured by its distance to the nearest scan point on a 0-4 mm scale (seen: under 2 mm)."""
    from ppm.render import DistanceScale, render_distance_map  # noqa: PLC0415

    scale = DistanceScale(0.0, 2.0 * SEEN_MM, "magma_r", f"distance to the scan, seen under {SEEN_MM:g} mm")
    return render_distance_map(vertices_mm, faces, scan_distance_per_vertex(vertices_mm, scan_points_mm), path,
                               title, scale=scale)


def write_coverage(name: str, pinnae: dict[str, str | os.PathLike], scans: dict[str, np.ndarray],
                   landmarks: str | os.PathLike, out_json: str | os.PathLike) -> dict:
    """Each ear's coverage (side -> its fitted pinna file and its scan's points, both in the left-ear frame, mm: the
    whole scan the personal-detail layer takes its evidence from; the template's ``landmarks`` file labels the
    regions) written atomically to ``out_json`` as {"seen_mm", "ears": {side: :func:`pinna_coverage` rows}, "advice"},
    with a picture per ear beside it (``coverage_<side>.png``)."""
    import json  # noqa: PLC0415

    import trimesh  # noqa: PLC0415

    from core.atomic import write_text_atomic  # noqa: PLC0415

    from .pinna_regions import landmark_positions_mm  # noqa: PLC0415

    ears = {}
    for side, pinna_path in pinnae.items():
        pinna = trimesh.load(pinna_path, process=False, force="mesh")
        ears[side] = pinna_coverage(pinna.vertices, pinna.faces, scans[side],
                                    landmark_positions_mm(pinna_path, landmarks))
        coverage_picture(pinna.vertices, pinna.faces, scans[side], Path(out_json).parent / f"coverage_{side}.png",
                         f"{name}, {side} ear: what the scan saw")
    result = {"seen_mm": SEEN_MM, "ears": ears, "advice": coverage_advice(ears)}
    write_text_atomic(out_json, json.dumps(result, indent=1) + "\n")
    return result
