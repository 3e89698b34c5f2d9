"""Fast closest points on a triangle surface whose vertices move but whose faces do not (mm).

For each query point the nearest vertex is found with a k-d tree and the exact closest point is
taken over the triangles around it (its one-ring). On a fine mesh this equals the true closest point
except in rare thin places; the final, reported distances use trimesh's exact query instead.
"""
from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import cKDTree


class OneRingSurface:
    """Closest-point queries on a mesh with fixed faces: update the vertices, query many points."""

    def __init__(self, faces: np.ndarray, n_vertices: int):
        self.faces = np.asarray(faces, dtype=np.int64)
        incidence = [[] for _ in range(n_vertices)]
        for face_index, face in enumerate(self.faces):
            for vertex in face:
                incidence[vertex].append(face_index)
        width = max(len(ring) for ring in incidence)
        self.rings = np.full((n_vertices, width), -1, dtype=np.int64)
        for vertex, ring in enumerate(incidence):
            self.rings[vertex, : len(ring)] = ring

    def closest(self, vertices_mm: np.ndarray, points_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest surface points for `points_mm`.

        Returns
        -------
        face_ids : (m,) int
            Triangle of each closest point.
        barycentric : (m, 3) float
            Its barycentric coordinates in that triangle.
        distance_mm : (m,) float
            Distance from each point to the surface.
        """
        _, nearest = cKDTree(vertices_mm).query(points_mm)
        candidates = self.rings[nearest]  # (m, w), -1 padded
        valid = candidates >= 0
        rows, cols = np.nonzero(valid)
        faces = candidates[rows, cols]
        triangles = vertices_mm[self.faces[faces]]
        closest = trimesh.triangles.closest_point(triangles, points_mm[rows])
        distance = np.full(candidates.shape, np.inf)
        distance[rows, cols] = np.linalg.norm(closest - points_mm[rows], axis=1)
        best = np.argmin(distance, axis=1)
        face_ids = candidates[np.arange(len(points_mm)), best]
        best_points = np.empty_like(points_mm)
        pick = valid[np.arange(len(points_mm)), best]
        flat = np.ravel_multi_index((rows, cols), candidates.shape)
        lookup = np.full(candidates.size, -1)
        lookup[flat] = np.arange(len(rows))
        chosen = lookup[np.ravel_multi_index((np.arange(len(points_mm)), best), candidates.shape)]
        best_points[pick] = closest[chosen[pick]]
        barycentric = trimesh.triangles.points_to_barycentric(vertices_mm[self.faces[face_ids]], best_points)
        return face_ids, barycentric, distance[np.arange(len(points_mm)), best]
