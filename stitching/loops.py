"""Boundary loops of open surfaces and the triangle strip that bridges two of them.

A loop is an ordered array of vertex indices; the strip between an outer loop (the hole cut into the
head) and an inner loop (the rim of the pinna's skin ring) is built by advancing along both loops,
always by the shorter of the two possible new rungs (a greedy "zipper"), which keeps every vertex of
both loops.
"""
from __future__ import annotations

import numpy as np
import trimesh
from trimesh.grouping import group_rows

from .errors import StitchError


def bowtie_vertices(mesh: trimesh.Trimesh) -> np.ndarray:
    """Vertices where boundary loops touch (more than one boundary edge leaves them in the faces' winding)."""
    edges = mesh.edges
    directed = edges[group_rows(np.sort(edges, axis=1), require_count=1)]
    starts, counts = np.unique(directed[:, 0], return_counts=True) if len(directed) else (np.empty(0, int), [])
    return starts[np.asarray(counts) > 1]


def without_bowties(mesh: trimesh.Trimesh, rounds: int = 20) -> trimesh.Trimesh:
    """``mesh`` with the faces at its bow-tie vertices (:func:`bowtie_vertices`) cut away, its largest edge-connected
    piece kept, until none is left: a region cut from a fine surface by a vertex mask (e.g. a reconstruction under
    a pinna's rim) leaves faces that touch the rest by one vertex only."""
    for _ in range(rounds):
        bad = bowtie_vertices(mesh)
        if bad.size == 0:
            return mesh
        kept = np.flatnonzero(~np.isin(mesh.faces, bad).any(axis=1))
        part = trimesh.Trimesh(mesh.vertices, mesh.faces[kept], process=False)
        pieces = trimesh.graph.connected_components(part.face_adjacency, nodes=np.arange(len(kept)))
        mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[kept[np.sort(max(pieces, key=len))]], process=False)
        mesh.remove_unreferenced_vertices()
    raise StitchError(f"the region keeps {len(bowtie_vertices(mesh))} bow-tie vertices after {rounds} rounds of "
                      "cleaning; the surface is not a manifold there")


def boundary_loops(mesh: trimesh.Trimesh) -> list[np.ndarray]:
    """Ordered vertex loops of the boundary edges, following the faces' winding (each boundary edge is
    used in the direction its face traverses it), longest first."""
    edges = mesh.edges  # directed, face by face
    unique = group_rows(np.sort(edges, axis=1), require_count=1)
    directed = edges[unique]
    following = {}
    for a, b in directed:
        if a in following:
            raise StitchError("a boundary vertex is shared by two boundary loops (a bow-tie); clean the mesh first")
        following[int(a)] = int(b)
    loops, seen = [], set()
    for start in following:
        if start in seen:
            continue
        loop, vertex = [], start
        while vertex not in seen:
            seen.add(vertex)
            loop.append(vertex)
            vertex = following.get(vertex)
            if vertex is None:
                raise StitchError("an open boundary chain does not close into a loop")
        loops.append(np.array(loop, dtype=np.int64))
    return sorted(loops, key=len, reverse=True)


def bridge_loops(vertices: np.ndarray, outer: np.ndarray, inner: np.ndarray,
                 metric: np.ndarray | None = None) -> np.ndarray:
    """Triangles (k, 3) joining two loops that run in opposite directions around the gap (as the hole
    of one surface and the rim of the other do when both surfaces are consistently wound). Each strip
    triangle traverses its loop edge against that loop's own direction, so the result is consistently
    wound with both surfaces. ``metric`` (same rows as ``vertices``, e.g. coordinates projected onto the
    plane of the gap) is what rung lengths are measured in; default the vertices themselves."""
    metric = vertices if metric is None else metric
    inner = inner[::-1]  # run both loops in the same direction
    p_outer, p_inner = vertices[outer], vertices[inner]
    start = int(np.argmin(np.linalg.norm(p_outer - p_inner[0], axis=1)))
    outer = np.roll(outer, -start)
    p_outer = vertices[outer]
    n_outer, n_inner = len(outer), len(inner)
    i = j = 0
    faces = []
    while i < n_inner or j < n_outer:
        a, b = inner[i % n_inner], outer[j % n_outer]
        next_a, next_b = inner[(i + 1) % n_inner], outer[(j + 1) % n_outer]
        if j >= n_outer:
            advance_inner = True
        elif i >= n_inner:
            advance_inner = False
        else:  # the shorter new rung keeps the strip from twisting
            advance_inner = (np.linalg.norm(metric[next_a] - metric[b])
                             <= np.linalg.norm(metric[a] - metric[next_b]))
        if advance_inner:
            faces.append([a, next_a, b])
            i += 1
        else:
            faces.append([b, a, next_b])
            j += 1
    return np.array(faces, dtype=np.int64)
