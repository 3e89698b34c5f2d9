"""How near a surface lies to the true ear over the region the stitch replaces (millimetres, project frame): both
directions, and the truth -> surface direction split into the parts a defective scan saw and those it never saw. Used
by ``benchmarks/align_defects.py`` and ``studies/layer_evidence.py`` to judge the PPM, its layer and a reconstruction
of the same scan alike."""
from __future__ import annotations

import numpy as np
import trimesh

from ppm.align.report import reverse_distances_mm
from ppm.align.target import Target
from stitching.replace_pinna import under_pinna

#: A truth point counts as seen by a scan when one of the scan's points lies this close (mm): the hard level resamples
#: to 2 mm (ppm/data/scan_defects.yaml); reporting.coverage and studies/committed import it from here.
SEEN_MM = 2.0


def seen_by(scan_points_mm: np.ndarray, points_mm: np.ndarray) -> np.ndarray:
    """Per point of ``points_mm``, whether a scan point lies within :data:`SEEN_MM`."""
    from scipy.spatial import cKDTree  # noqa: PLC0415

    return cKDTree(np.asarray(scan_points_mm, np.float64)).query(np.asarray(points_mm, np.float64))[0] < SEEN_MM


def completed_where_blind(scan: trimesh.Trimesh, truth: trimesh.Trimesh,
                          normal_agreement_deg: float = 60.0) -> trimesh.Trimesh:
    """An oracle scan: ``truth`` (the clean crop, mm, same frame as ``scan``) with each vertex the scan saw
    (:func:`seen_by`, and facing the way the scan's surface there faces, within ``normal_agreement_deg``) moved onto
    its closest point on the scan's surface. The scan's noise where it saw, the truth where it was blind (holes, the
    partial crop, the back of the flap), on the truth's one connected surface, so that the pinna's segmentation keeps
    all of it. What a better scanner would have delivered: it tells what the blind parts cost, no one gets it."""
    completed = np.asarray(truth.vertices, np.float64).copy()
    seen = np.flatnonzero(seen_by(scan.vertices, completed))  # only these can move: the rest is blind
    closest, _, triangle = trimesh.proximity.closest_point(scan, completed[seen])
    facing = np.einsum("ij,ij->i", scan.face_normals[triangle], truth.vertex_normals[seen])
    moved = facing > np.cos(np.radians(normal_agreement_deg))
    completed[seen[moved]] = closest[moved]
    return trimesh.Trimesh(completed, truth.faces, process=False)


def heights_where_seen(scan: trimesh.Trimesh, truth: trimesh.Trimesh,
                       reach_mm: float = 3.0) -> tuple[trimesh.Trimesh, dict]:
    """An oracle scan whose seen parts keep the scan's own deviations: ``truth`` (the clean crop, mm, same frame as
    ``scan``) with each vertex the scan saw (:func:`seen_by`) moved along its normal, either way, to where that line
    meets the scan's surface (the nearest crossing within ``reach_mm``; where none, its closest point on the scan),
    and the truth where the scan was blind. :func:`completed_where_blind` moves each vertex to its closest point on
    the scan instead, which picks the nearest of the rough surface's facets and so leaves less of the scan's noise
    than the scan has; a crossing along the normal keeps its height there, noise, spikes and outlier tents included.
    One connected surface (the truth's), so that the pinna's segmentation keeps it all. Returns the surface and how
    its seen vertices were placed (counts, and the median / p95 of their moves, mm)."""
    completed = np.asarray(truth.vertices, np.float64).copy()
    seen = np.flatnonzero(seen_by(scan.vertices, completed))
    origins, normals = completed[seen], np.asarray(truth.vertex_normals)[seen]
    nearest = np.full(len(seen), np.inf)
    crossing = origins.copy()
    for sign in (1.0, -1.0):
        locations, ray, _ = scan.ray.intersects_location(origins, sign * normals, multiple_hits=True)
        if not len(ray):
            continue
        distance = np.linalg.norm(locations - origins[ray], axis=1)
        order = np.lexsort((distance, ray))  # per ray, its nearest crossing first
        first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]]
        better = distance[first] < nearest[ray[first]]
        nearest[ray[first][better]] = distance[first][better]
        crossing[ray[first][better]] = locations[first][better]
    crossed = nearest <= reach_mm
    if (~crossed).any():
        crossing[~crossed] = trimesh.proximity.closest_point(scan, origins[~crossed])[0]
    completed[seen] = crossing
    moves = np.linalg.norm(crossing - origins, axis=1)
    report = {"seen_vertices": int(len(seen)), "crossed": int(crossed.sum()), "closest_instead": int((~crossed).sum()),
              "move_median_mm": round(float(np.median(moves)), 4) if len(moves) else None,
              "move_p95_mm": round(float(np.percentile(moves, 95)), 4) if len(moves) else None}
    return trimesh.Trimesh(completed, truth.faces, process=False), report


def region_distances(truth: Target, seen: np.ndarray, guide: trimesh.Trimesh, vertices_mm: np.ndarray,
                     faces: np.ndarray) -> dict[str, float]:
    """Over the region the stitch replaces under ``guide`` (the PPM fitted to the scan): truth -> surface and
    surface -> truth median and p95 (mm), and truth -> surface over the truth points the scan saw (``seen``, per truth
    point) and those it never saw."""
    inside = under_pinna(truth.points_mm, guide)
    surface = trimesh.Trimesh(vertices_mm, faces, process=False)
    forward = trimesh.proximity.closest_point(surface, truth.points_mm[inside])[1]
    backward, counts = reverse_distances_mm(truth, vertices_mm, boundary_margin_mm=1.0)
    counts &= under_pinna(np.asarray(vertices_mm), guide)
    seen_inside = seen[inside]
    out = {}
    for name, values in (("truth_to_fit", forward), ("fit_to_truth", backward[counts]),
                         ("seen", forward[seen_inside]), ("unseen", forward[~seen_inside])):
        out[f"{name}_median_mm"] = float(np.median(values)) if len(values) else float("nan")
        out[f"{name}_p95_mm"] = float(np.percentile(values, 95)) if len(values) else float("nan")
    return out
