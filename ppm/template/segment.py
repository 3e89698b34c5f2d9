"""Segmentation of the pinna in a crop that also holds head skin (millimetres, project frame).

The pinna is a thin flap of cartilage: from a point on it, a ray cast inward along the surface
normal meets the other side of the flap within a few millimetres, whereas from the skin of the
head it travels into the head and meets nothing in the crop. The convex hull of these "flap"
points seen from the side (+y) covers the concha and the ear canal too, and it is widened by a
margin to keep a short ring of surrounding skin.
"""
from __future__ import annotations

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, cKDTree

from ..errors import PpmError

#: A flap thicker than this (mm) is not pinna cartilage.
MAX_FLAP_THICKNESS_MM = 12.0
#: Nor is one thinner than this (skin on both sides alone is thicker): such hits come from scan noise
#: and outlier spikes next to the ray's start.
MIN_FLAP_THICKNESS_MM = 1.0
#: Rays are cast from at most this many vertices (speed); the footprint is a 2-D mask anyway.
MAX_RAY_VERTICES = 4000
#: Flap points closer than this (mm, side view) belong to one cluster; clusters holding less than
#: MIN_CLUSTER_SHARE of the flap points are scan defects (spikes, noisy skin), not pinna.
CLUSTER_LINK_MM = 5.0
MIN_CLUSTER_SHARE = 0.05


def flap_thickness_mm(mesh: trimesh.Trimesh, vertex_ids: np.ndarray) -> np.ndarray:
    """Distance (mm) from each given vertex, inward along its normal, to the next surface; inf if none."""
    normals = mesh.vertex_normals[vertex_ids]
    origins = mesh.vertices[vertex_ids] - normals * 0.05
    locations, ray_ids, _ = mesh.ray.intersects_location(origins, -normals, multiple_hits=False)
    thickness = np.full(len(vertex_ids), np.inf)
    thickness[ray_ids] = np.linalg.norm(locations - origins[ray_ids], axis=1)
    return thickness


def flap_points_xz(mesh: trimesh.Trimesh, seed: int = 0) -> np.ndarray:
    """Side-view (x, z) coordinates in mm of the vertices that lie on a thin flap (the pinna).

    Raises
    ------
    PpmError
        If no flap-like structure is found (not a pinna, or far too coarse a mesh).
    """
    rng = np.random.default_rng(seed)
    n = len(mesh.vertices)
    ids = np.arange(n) if n <= MAX_RAY_VERTICES else np.sort(rng.choice(n, MAX_RAY_VERTICES, replace=False))
    thickness = flap_thickness_mm(mesh, ids)
    flap = (thickness >= MIN_FLAP_THICKNESS_MM) & (thickness < MAX_FLAP_THICKNESS_MM)
    flap_xz = without_stray_clusters(mesh.vertices[ids][flap][:, [0, 2]])
    if len(flap_xz) < 50:
        raise PpmError(
            f"found only {len(flap_xz)} points on a thin flap: this mesh does not look like a pinna crop "
            "(or it is far coarser than 2 mm)"
        )
    return flap_xz


def without_stray_clusters(points_xz: np.ndarray) -> np.ndarray:
    """The side-view flap points (mm) without the small clusters that outlier spikes and noisy head skin
    leave far from the pinna (a real pinna's flap points form one cluster at CLUSTER_LINK_MM)."""
    if len(points_xz) == 0:
        return points_xz
    pairs = cKDTree(points_xz).query_pairs(CLUSTER_LINK_MM, output_type="ndarray")
    links = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points_xz),) * 2)
    _, label = connected_components(links, directed=False)
    size = np.bincount(label)
    return points_xz[size[label] >= MIN_CLUSTER_SHARE * len(points_xz)]


def distance_to_hull_mm(hull_xz: np.ndarray, points_xz: np.ndarray) -> np.ndarray:
    """Distance (mm) in the side view from each point to the convex polygon `hull_xz` (0 inside)."""
    start, end = hull_xz, np.roll(hull_xz, -1, axis=0)
    edge = end - start
    t = np.clip(((points_xz[:, None, :] - start) * edge).sum(-1) / (edge * edge).sum(-1), 0.0, 1.0)
    nearest = start + t[..., None] * edge
    distance = np.linalg.norm(points_xz[:, None, :] - nearest, axis=-1).min(axis=1)
    # inside a counter-clockwise convex polygon every edge has the point on its left
    cross = edge[:, 0] * (points_xz[:, None, 1] - start[:, 1]) - edge[:, 1] * (points_xz[:, None, 0] - start[:, 0])
    distance[(cross >= 0).all(axis=1)] = 0.0
    return distance


def pinna_region(mesh: trimesh.Trimesh, margin_mm: float = 6.0) -> np.ndarray:
    """Boolean per-vertex mask of the pinna plus a ring of skin `margin_mm` wide.

    The pinna outline is the convex hull, seen from the side (+y), of the flap points; the region is
    that outline widened by `margin_mm`. Of the surface inside it, only the connected part holding
    the pinna is kept.
    """
    flap_xz = flap_points_xz(mesh)
    hull = ConvexHull(flap_xz)
    hull_xz = flap_xz[hull.vertices]  # counter-clockwise in 2-D
    distance = distance_to_hull_mm(hull_xz, mesh.vertices[:, [0, 2]])
    inside = distance <= margin_mm
    face_in = inside[mesh.faces].all(axis=1)
    sub_faces = np.flatnonzero(face_in)
    adjacency = mesh.face_adjacency[face_in[mesh.face_adjacency].all(axis=1)]
    components = trimesh.graph.connected_components(adjacency, nodes=sub_faces, min_len=1)
    best = max(components, key=len)
    region = np.zeros(len(mesh.vertices), dtype=bool)
    region[np.unique(mesh.faces[best])] = True
    return region


def crop_to_region(mesh: trimesh.Trimesh, vertex_mask: np.ndarray) -> trimesh.Trimesh:
    """Sub-mesh of the faces whose three vertices are in `vertex_mask` (unreferenced vertices dropped)."""
    faces = mesh.faces[vertex_mask[mesh.faces].all(axis=1)]
    sub = trimesh.Trimesh(mesh.vertices, faces, process=False)
    sub.remove_unreferenced_vertices()
    return sub
