"""Facing sheets of the template pinna and a barrier that keeps them apart while fitting (mm, project frame).

Where the pinna folds over itself (the helix curled over the scapha, the front and back of the helix rim, the
antitragus over the concha) two parts of the surface lie a few millimetres apart in space but far apart along it.
The fold barrier of :mod:`ppm.align.fit` keeps each triangle from turning over; it cannot stop one sheet from
passing through another, and on a scan with holes there the data term does not either (P143's hard scan: the helix
went through the scapha at 168 faces, which no boundary element mesh may do).

So the template's vertex pairs on facing sheets are found once: closer than ``reach_mm`` in space, at least
``geodesic_ratio`` times that far along the surface, and with the one vertex clearly on one side of the other's
tangent plane (``|cos| >= side_cosine`` between their offset and the normal). Each pair keeps the side it has in the
template. While fitting, a pair whose vertex ``i`` lies over the tangent plane of ``j`` (within ``over_mm`` of ``j``
along the plane) and nearer than its margin on the template's side of it (or beyond it) costs the square of that
shortfall: ``r = margin - side * (v_i - v_j) . n_j`` with ``margin = min(margin_mm, side * d0 / 2)``, so the
template itself pays nothing.
"""
from __future__ import annotations

import dataclasses
import hashlib

import numpy as np
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from ..geodesic import edge_graph


@dataclasses.dataclass(frozen=True)
class FacingSheets:
    """Vertex pairs (i, j) of the template on facing sheets: ``i`` must stay on ``side`` (+1 or -1) of the tangent
    plane of ``j``, at least ``margin_mm`` from it."""

    i: np.ndarray
    j: np.ndarray
    side: np.ndarray
    margin_mm: np.ndarray

    def __len__(self) -> int:
        return len(self.i)


_CACHE: dict[tuple, FacingSheets] = {}


def vertex_normals(vertices_mm: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n, 3) area-weighted unit vertex normals (the faces' winding decides the side)."""
    tri = vertices_mm[faces]
    face_normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals = np.zeros_like(vertices_mm)
    for corner in range(3):
        np.add.at(normals, faces[:, corner], face_normals)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)


def facing_sheets(vertices_mm: np.ndarray, faces: np.ndarray, reach_mm: float = 5.0, geodesic_ratio: float = 2.0,
                  side_cosine: float = 0.3, margin_mm: float = 0.3) -> FacingSheets:
    """The template's vertex pairs on facing sheets (module docstring); cached per template and settings."""
    vertices_mm = np.asarray(vertices_mm, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    key = (hashlib.sha1(vertices_mm.tobytes() + faces.tobytes()).hexdigest(), reach_mm, geodesic_ratio,
           side_cosine, margin_mm)
    if key not in _CACHE:
        _CACHE[key] = _facing_sheets(vertices_mm, faces, reach_mm, geodesic_ratio, side_cosine, margin_mm)
    return _CACHE[key]


def _facing_sheets(vertices_mm: np.ndarray, faces: np.ndarray, reach_mm: float, geodesic_ratio: float,
                   side_cosine: float, margin_mm: float) -> FacingSheets:
    pairs = cKDTree(vertices_mm).query_pairs(reach_mm, output_type="ndarray")
    graph = edge_graph(vertices_mm, faces)
    limit = geodesic_ratio * reach_mm
    keep = np.zeros(len(pairs), dtype=bool)
    order = np.argsort(pairs[:, 0], kind="stable")
    pairs = pairs[order]
    sources = np.unique(pairs[:, 0])
    for chunk in np.array_split(sources, max(1, len(sources) // 400)):
        along = dijkstra(graph, directed=False, indices=chunk, limit=limit)
        rows = np.searchsorted(chunk, pairs[:, 0])
        inside = (rows < len(chunk)) & (chunk[np.minimum(rows, len(chunk) - 1)] == pairs[:, 0])
        apart = np.linalg.norm(vertices_mm[pairs[inside, 0]] - vertices_mm[pairs[inside, 1]], axis=1)
        keep[inside] = along[rows[inside], pairs[inside, 1]] >= geodesic_ratio * apart
    pairs = pairs[keep]
    pairs = np.concatenate([pairs, pairs[:, ::-1]])  # each vertex is held off the other's plane
    normals = vertex_normals(vertices_mm, faces)
    offset = vertices_mm[pairs[:, 0]] - vertices_mm[pairs[:, 1]]
    height = np.einsum("ij,ij->i", offset, normals[pairs[:, 1]])
    clear = np.abs(height) >= side_cosine * np.linalg.norm(offset, axis=1)
    pairs, height = pairs[clear], height[clear]
    side = np.sign(height)
    return FacingSheets(pairs[:, 0], pairs[:, 1], side, np.minimum(margin_mm, 0.5 * np.abs(height)))


def sheet_terms(sheets: FacingSheets, vertices_mm: np.ndarray, faces: np.ndarray, over_mm: float = 1.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs that press too close (or through): their indices into ``sheets``, residuals in mm (margin minus
    the signed height of ``i`` over ``j``'s tangent plane, positive when too close) and the plane normals ``n_j``
    (the residual's derivative is ``-side * n_j`` by ``v_i`` and ``+side * n_j`` by ``v_j``)."""
    normals = vertex_normals(vertices_mm, faces)[sheets.j]
    offset = vertices_mm[sheets.i] - vertices_mm[sheets.j]
    height = np.einsum("ij,ij->i", offset, normals)
    along = np.linalg.norm(offset - height[:, None] * normals, axis=1)
    residual = sheets.margin_mm - sheets.side * height
    pressing = np.flatnonzero((residual > 0.0) & (along <= over_mm))
    return pressing, residual[pressing], normals[pressing]
