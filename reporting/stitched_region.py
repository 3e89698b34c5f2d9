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


def with_blind_parts(scan: trimesh.Trimesh, truth: trimesh.Trimesh) -> trimesh.Trimesh:
    """An oracle scan that keeps the scan as it is: ``scan`` (mm) with the faces of ``truth`` (the clean crop, same
    frame) whose three vertices the scan was blind to (:func:`seen_by`) added as further pieces. Unlike
    :func:`completed_where_blind`, the seen parts keep the scan's own points, noise, outliers and sampling, so that
    a listener fitted to it differs from the hard listener only where the scan never saw: what a perfect guess of the
    unseen parts, and nothing else, is worth. The added pieces are not joined to the scan; the fit segments the
    scan's largest piece, the personal-detail layer takes its evidence from all of them."""
    blind = ~seen_by(scan.vertices, truth.vertices)
    faces = np.asarray(truth.faces)[blind[np.asarray(truth.faces)].all(axis=1)]
    patch = trimesh.Trimesh(np.asarray(truth.vertices, np.float64), faces, process=False)
    patch.remove_unreferenced_vertices()
    offset = len(scan.vertices)
    return trimesh.Trimesh(np.vstack([np.asarray(scan.vertices, np.float64), patch.vertices]),
                           np.vstack([np.asarray(scan.faces), np.asarray(patch.faces) + offset]), process=False)


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
