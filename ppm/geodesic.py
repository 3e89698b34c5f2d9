"""Geodesic distances and paths on a triangle mesh (millimetres), along its edges (Dijkstra).

Distances along the surface keep a bone or a shape key from reaching across a fold (helix to
antihelix across the scapha) the way straight-line distances would.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import dijkstra


def edge_graph(vertices_mm: np.ndarray, faces: np.ndarray) -> csr_matrix:
    """Sparse symmetric (n, n) matrix of edge lengths in mm."""
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    lengths = np.linalg.norm(vertices_mm[edges[:, 0]] - vertices_mm[edges[:, 1]], axis=1)
    n = len(vertices_mm)
    graph = coo_matrix((np.r_[lengths, lengths], (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                       shape=(n, n))
    return graph.tocsr()


def distance_from(graph: csr_matrix, sources: np.ndarray) -> np.ndarray:
    """(n,) geodesic distance in mm from the nearest of the `sources` vertices (inf if unreachable)."""
    return dijkstra(graph, directed=False, indices=np.asarray(sources, dtype=np.int64), min_only=True)


def rim_vertices(faces: np.ndarray) -> np.ndarray:
    """Indices of the vertices on the mesh's open boundary (for a PPM: the skin ring's rim, where the stitch joins)."""
    edges = np.sort(np.asarray(faces)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    return np.unique(unique[counts == 1])


def distance_from_rim_mm(vertices_mm: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n,) geodesic distance in mm of every vertex from the mesh's open boundary (:func:`rim_vertices`)."""
    return distance_from(edge_graph(np.asarray(vertices_mm), np.asarray(faces)), rim_vertices(faces))


def path_through(graph: csr_matrix, waypoints: list[int]) -> np.ndarray:
    """Vertex ids of the shortest edge path visiting `waypoints` in order (duplicates removed)."""
    path: list[int] = [int(waypoints[0])]
    for start, end in zip(waypoints[:-1], waypoints[1:]):
        _, predecessors = dijkstra(graph, directed=False, indices=int(start), return_predecessors=True)
        leg = [int(end)]
        while leg[-1] != start:
            previous = predecessors[leg[-1]]
            if previous < 0:
                raise ValueError(f"vertex {end} cannot be reached from vertex {start} on the mesh")
            leg.append(int(previous))
        path.extend(leg[::-1][1:])
    return np.array(path, dtype=np.int64)
