"""Validation of a BEM head mesh (millimetres): closed, manifold, no self-intersections, outward
normals, edge lengths at the pinna and overall, element count, the highest frequency with six
elements per wavelength, and how far the stitched pinna moved from the aligned PPM pinna."""
from __future__ import annotations

import numpy as np
import trimesh

from mesh2hrtf_io.checks import SLIVER_ANGLE_DEG, mesh_problems, min_angles_deg
from mesh2hrtf_io.constants import ELEMENTS_PER_WAVELENGTH, SPEED_OF_SOUND_M_S

from .remesh import face_distance_to, folded_faces, self_intersections


def edge_lengths_of(mesh: trimesh.Trimesh, faces: np.ndarray) -> np.ndarray:
    """Lengths (mm) of the unique edges of the selected faces (bool mask)."""
    return mesh.edges_unique_length[np.unique(mesh.faces_unique_edges[faces].ravel())]


def validate_head(mesh: trimesh.Trimesh, pinna: trimesh.Trimesh | None = None, pinna_band_mm: float = 1.0) -> dict:
    """Numbers a BEM user checks before solving. ``pinna`` (the aligned PPM pinna, mm) defines the pinna
    region (faces within ``pinna_band_mm`` of it) and the distance check."""
    problems = mesh_problems(mesh.vertices, mesh.faces)
    edges = mesh.edges_unique_length
    angles = min_angles_deg(mesh.vertices, mesh.faces)
    report = {
        "closed": bool(mesh.is_watertight), "manifold": not any("manifold" in p or "open" in p for p in problems),
        "problems": problems, "self_intersecting_faces": self_intersections(mesh),
        "volume_mm3": float(mesh.volume), "normals_outward": bool(mesh.volume > 0), "n_triangles": int(len(mesh.faces)),
        "n_vertices": int(len(mesh.vertices)),
        "min_angle_deg": float(angles.min()), "sliver_faces": int((angles < SLIVER_ANGLE_DEG).sum()),
        "folded_faces": int(folded_faces(mesh).sum()),
        "edge_mm": {"median": float(np.median(edges)), "p95": float(np.percentile(edges, 95)), "max": float(edges.max())},
    }
    report["max_frequency_hz_6_per_wavelength"] = float(SPEED_OF_SOUND_M_S * 1000 / (ELEMENTS_PER_WAVELENGTH * edges.max()))
    if pinna is not None:
        region = face_distance_to(np.asarray(pinna.vertices), mesh) < pinna_band_mm
        pinna_edges = edge_lengths_of(mesh, region)
        report["pinna_edge_mm"] = {"median": float(np.median(pinna_edges)), "p5": float(np.percentile(pinna_edges, 5)),
                                   "p95": float(np.percentile(pinna_edges, 95)), "max": float(pinna_edges.max())}
        report["max_frequency_hz_6_per_wavelength_pinna"] = float(
            SPEED_OF_SOUND_M_S * 1000 / (ELEMENTS_PER_WAVELENGTH * np.percentile(pinna_edges, 95)))
        # one-sided distance from the aligned PPM pinna (its surface samples) to the final head surface
        samples = trimesh.sample.sample_surface_even(pinna, 20000, seed=1)[0] if len(pinna.faces) else pinna.vertices
        _, distance, _ = trimesh.proximity.closest_point(mesh, samples)
        report["pinna_to_head_mm"] = {"median": float(np.median(distance)), "p95": float(np.percentile(distance, 95)),
                                      "max": float(distance.max())}
    report["ok"] = bool(report["closed"] and not problems and report["self_intersecting_faces"] == 0
                        and report["sliver_faces"] == 0 and report["folded_faces"] == 0)
    return report
