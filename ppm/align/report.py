"""Geometric evaluation and outputs of an alignment (millimetres, project frame).

The error measure is the paper's: the point-wise one-sided Hausdorff distance, i.e. for every
target (scan) point the distance to the closest point of the aligned PPM surface. Outputs are
written atomically: parameters (CSV, JSON), the aligned pinna (PLY), the posed rig (.blend), the
target points with their distances as PLY vertex quality (MeshLab colours it directly), and a
JSON summary.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from core.atomic import atomic_path, write_text_atomic
from core.self_intersections import self_intersecting_faces
from ..model import PinnaModel
from .fit import AlignmentResult
from .target import Target

#: A fit is flagged as poor when its median distance exceeds this (mm) ...
POOR_FIT_MEDIAN_MM = 1.0
#: ... or when more than POOR_FIT_FAR_SHARE of the scan lies farther than POOR_FIT_DISTANCE_MM.
POOR_FIT_DISTANCE_MM = 3.0
POOR_FIT_FAR_SHARE = 0.1

OUTPUT_NAMES = {
    "parameters_csv": "parameters.csv",
    "parameters_json": "parameters.json",
    "aligned_ply": "aligned_pinna.ply",
    "blend": "aligned_pinna.blend",
    "distances_ply": "distances.ply",
    "summary": "summary.json",
}


def one_sided_distances_mm(target: Target, vertices_mm: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n,) distance in mm from every target point to the surface (vertices_mm, faces)."""
    mesh = trimesh.Trimesh(vertices_mm, faces, process=False)
    return trimesh.proximity.closest_point(mesh, target.points_mm)[1]


def reverse_distances_mm(target: Target, vertices_mm: np.ndarray, boundary_margin_mm: float = 1.0
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Model -> scan: (distance in mm from every model vertex to the scan surface, mask of the vertices that
    count). A vertex counts when its closest scan point lies at least ``boundary_margin_mm`` from the scan's
    open boundary (the crop's edge and its holes): model surface beyond the scanned region has nothing to be
    compared with. Without a scan surface (points only) every vertex counts, measured to the points."""
    vertices_mm = np.asarray(vertices_mm, dtype=np.float64)
    mesh = target.mesh
    if mesh is None or len(mesh.faces) == 0:
        distance = cKDTree(target.points_mm).query(vertices_mm)[0]
        return distance, np.ones(len(vertices_mm), dtype=bool)
    closest, distance, _ = trimesh.proximity.closest_point(mesh, vertices_mm)
    samples = boundary_samples(mesh)
    if len(samples) == 0:
        return distance, np.ones(len(vertices_mm), dtype=bool)
    away = cKDTree(samples).query(closest)[0] >= boundary_margin_mm
    return distance, away


def boundary_samples(mesh: trimesh.Trimesh, per_edge: int = 5) -> np.ndarray:
    """(m, 3) points along the open boundary edges of ``mesh`` (the crop's edge and the rims of its holes), each
    edge sampled at ``per_edge`` points so that a long edge's middle is not missed; empty for a closed mesh."""
    unique, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    ends = np.asarray(mesh.vertices)[unique[counts == 1]]
    if len(ends) == 0:
        return np.zeros((0, 3))
    steps = np.linspace(0.0, 1.0, per_edge)[:, None, None]
    return (ends[None, :, 0] * (1 - steps) + ends[None, :, 1] * steps).reshape(-1, 3)


def distance_summary(distance_mm: np.ndarray) -> dict[str, float]:
    """Median, mean, 95th percentile, maximum (mm) and the share of points under 1 mm."""
    return {
        "median_mm": round(float(np.median(distance_mm)), 4),
        "mean_mm": round(float(np.mean(distance_mm)), 4),
        "p95_mm": round(float(np.percentile(distance_mm, 95)), 4),
        "max_mm": round(float(np.max(distance_mm)), 4),
        "share_under_1mm": round(float(np.mean(distance_mm < 1.0)), 4),
        "n_points": int(len(distance_mm)),
    }


def write_distances_ply(path: str | Path, target: Target, distance_mm: np.ndarray) -> Path:
    """The target points (with the target surface where it has one) and per-vertex `quality` = distance."""
    path = Path(path)
    mesh = target.mesh
    on_mesh = len(mesh.vertices) == len(target.points_mm) and np.array_equal(mesh.vertices, target.points_mm)
    faces = mesh.faces if on_mesh else np.zeros((0, 3), dtype=np.int64)  # points only: a faceless mesh
    out = trimesh.Trimesh(target.points_mm, faces, process=False)
    out.vertex_attributes["quality"] = np.asarray(distance_mm, dtype=np.float32)
    with atomic_path(path) as tmp:
        out.export(tmp, file_type="ply")
    return path


def write_alignment(out_dir: str | Path, model: PinnaModel, target: Target, result: AlignmentResult,
                    extra: dict | None = None) -> dict:
    """Write every output of an alignment into `out_dir`; returns the summary dict."""
    out_dir = Path(out_dir)
    distance = one_sided_distances_mm(target, result.vertices_mm, model.faces)
    warnings = list(result.warnings)
    far = float(np.mean(distance > POOR_FIT_DISTANCE_MM))
    if np.median(distance) > POOR_FIT_MEDIAN_MM or far > POOR_FIT_FAR_SHARE:
        warnings.append(f"POOR FIT: median distance {np.median(distance):.2f} mm, {100 * far:.0f} % of the scan "
                        f"farther than {POOR_FIT_DISTANCE_MM:g} mm; check the scan (side, units, is it a pinna?)")
    crossing = len(self_intersecting_faces(result.vertices_mm, model.faces))
    if crossing:
        # the sheet barrier holds the facing sheets the template has (ppm.align.sheets), not a part pushed through
        # one it never faced; the remesh relaxes such faces, the layer can untangle them with evidence
        warnings.append(f"the fitted PPM crosses itself at {crossing} faces (where the scan did not see a fold, e.g. "
                        "the helix over the scapha); the remesh relaxes them, a scan of that part mends it")
    summary = {
        "target": target.source,
        "distance_target_to_ppm": distance_summary(distance),
        "seconds": round(result.seconds, 2),
        "global_pose_start": result.start_index,
        "iterations": len(result.history),
        "folded_faces": result.folded_faces,
        "self_intersecting_faces": crossing,
        "sheet_pairs_pressing": result.sheet_pairs_pressing,
        "warnings": warnings,
        **(extra or {}),
    }
    result.parameters.write(out_dir / OUTPUT_NAMES["parameters_csv"])
    result.parameters.write(out_dir / OUTPUT_NAMES["parameters_json"])
    model.set_parameters(result.parameters)
    model.export(out_dir / OUTPUT_NAMES["aligned_ply"])
    model.save_blend(out_dir / OUTPUT_NAMES["blend"])
    write_distances_ply(out_dir / OUTPUT_NAMES["distances_ply"], target, distance)
    write_text_atomic(out_dir / OUTPUT_NAMES["summary"], json.dumps(summary, indent=2) + "\n")
    return summary
