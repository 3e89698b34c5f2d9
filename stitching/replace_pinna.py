"""Replacing the left pinna of a head mesh by an aligned PPM pinna (millimetres, project frame:
+x front, +y left, +z up, origin at the interaural centre).

The PPM pinna is an open surface whose single boundary (the rim of its skin ring) lies on the head's
skin. The head faces that the pinna covers — those with a vertex that, seen along the pinna's base
normal, falls inside the rim grown by ``gap_mm`` and lies within ``reach_mm`` of the pinna — are cut
away, leaving one hole at least ``gap_mm`` wider than the rim; a zipper strip joins the hole to the rim. The
result is one closed, consistently wound surface; the rest of the head (the right pinna included)
keeps its vertices and triangles unchanged.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import trimesh
from matplotlib.path import Path as PolygonPath
from scipy.spatial import cKDTree

from mesh2hrtf_io.checks import mesh_problems

from .errors import StitchError
from .loops import boundary_loops, bridge_loops, without_bowties


@dataclasses.dataclass(frozen=True)
class StitchedHead:
    """The stitched surface and, per face, where it came from: 0 = head, 1 = PPM pinna, 2 = seam strip."""

    mesh: trimesh.Trimesh
    origin: np.ndarray
    removed_head_faces: int
    rim_gap_mm: float


def _check_pinna(pinna: trimesh.Trimesh, source: str) -> np.ndarray:
    vertices = np.asarray(pinna.vertices)
    if len(pinna.faces) == 0 or not np.isfinite(vertices).all():
        raise StitchError(f"{source}: the pinna mesh is empty or holds NaN/inf coordinates")
    extent = float(np.linalg.norm(np.ptp(vertices, axis=0)))
    if not 20.0 <= extent <= 200.0:
        raise StitchError(f"{source}: the pinna is {extent:.3g} units across; a pinna is 50-100 mm: give it in "
                          "millimetres (a mesh in metres must be scaled by 1000)")
    if vertices[:, 1].mean() < 30.0:
        raise StitchError(f"{source}: the pinna lies at y = {vertices[:, 1].mean():.1f} mm; a LEFT pinna lies at "
                          "y > 30 mm (+y = left). Mirror a right pinna (y -> -y) or align it to the left ear first")
    loops = boundary_loops(pinna)
    if not loops:
        raise StitchError(f"{source}: the pinna is closed; it must be open along the rim of its skin ring")
    if len(loops) > 1:
        raise StitchError(f"{source}: the pinna has {len(loops)} boundary loops; it must have one (the rim of its "
                          f"skin ring); close the {len(loops) - 1} hole(s) first")
    return loops[0]


def _covered_by_pinna(head: trimesh.Trimesh, pinna: trimesh.Trimesh, rim: np.ndarray, gap_mm: float,
                      reach_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Head vertices under the pinna: near it, on its side of the head, and inside its rim seen along the ear
    axis, the rim grown by ``gap_mm`` (shrunk for a negative gap). Returns (mask, rim centre, (3, 2) basis of
    the rim's plane)."""
    rim_points = np.asarray(pinna.vertices)[rim]
    centre = rim_points.mean(axis=0)
    _, _, axes = np.linalg.svd(rim_points - centre)
    normal = axes[2] if axes[2][1] >= 0 else -axes[2]  # the ear's outward axis, towards +y
    plane = np.stack([axes[0], axes[1]], axis=1)
    points = np.asarray(head.vertices)
    near_pinna = cKDTree(pinna.vertices).query(points, distance_upper_bound=reach_mm)[0] < reach_mm
    lateral = (points - centre) @ normal > -reach_mm
    rim_2d = (rim_points - centre) @ plane
    points_2d = (points - centre) @ plane
    inside = PolygonPath(rim_2d).contains_points(points_2d)
    to_rim = cKDTree(rim_2d).query(points_2d)[0]
    outline = (inside | (to_rim < gap_mm)) if gap_mm >= 0 else (inside & (to_rim >= -gap_mm))
    return near_pinna & lateral & outline, centre, plane


def under_pinna(points_mm: np.ndarray, pinna: trimesh.Trimesh, *, gap_mm: float = 0.0, reach_mm: float = 25.0,
                pinna_source: str = "pinna mesh") -> np.ndarray:
    """Which of ``points_mm`` (n, 3; mm, project frame) lie in the region the stitch replaces under an aligned pinna
    (near it, on its side of the head, inside its rim grown by ``gap_mm``): the region a pinna is judged over."""
    rim = _check_pinna(pinna, pinna_source)

    class _Points:  # _covered_by_pinna reads only the vertices of the head
        vertices = np.asarray(points_mm, dtype=np.float64)

    return _covered_by_pinna(_Points(), pinna, rim, gap_mm, reach_mm)[0]


def _components(mesh: trimesh.Trimesh, faces: np.ndarray) -> list[np.ndarray]:
    """The edge-connected parts of ``faces`` (face indices of ``mesh``), each as face indices of ``mesh``."""
    part = trimesh.Trimesh(mesh.vertices, mesh.faces[faces], process=False)
    return [faces[c] for c in trimesh.graph.connected_components(part.face_adjacency, nodes=np.arange(len(faces)))]


def _largest_component(mesh: trimesh.Trimesh, faces: np.ndarray) -> np.ndarray:
    """The largest edge-connected part of ``faces`` (face indices of ``mesh``), sorted."""
    return np.sort(max(_components(mesh, faces), key=len))


def own_pinna_region(head: trimesh.Trimesh, pinna: trimesh.Trimesh, *, inset_mm: float = 1.0,
                     reach_mm: float = 25.0, pinna_source: str = "pinna mesh",
                     tidy_boundary: bool = False) -> trimesh.Trimesh:
    """The head's own left pinna under an aligned pinna ``pinna``: the head faces inside its rim (by at least
    ``inset_mm``), as one open surface with one boundary, in mm. Stitched back with :func:`replace_pinna`
    and remeshed like a PPM pinna, it is the control that shows what the stitch and remesh path alone
    changes. ``tidy_boundary`` cuts away faces that touch the region by one vertex only (:func:`without_bowties`),
    as a fine surface cut by a vertex mask has (a reconstructed scan; a head's own region is left as it is)."""
    rim = _check_pinna(pinna, pinna_source)
    covered, _, _ = _covered_by_pinna(head, pinna, rim, -inset_mm, reach_mm)
    inside = covered[head.faces].all(axis=1)
    if not inside.any():
        raise StitchError(f"{pinna_source}: no head face lies inside the pinna's rim; is it placed at this head's left ear?")
    # holes in the region (faces under the helix fold or deep in the concha that the tests above miss) belong to
    # it: the region is everything the rest of the head (the largest outside part) does not reach
    rest = _largest_component(head, np.flatnonzero(~inside))
    region_faces = _largest_component(head, np.setdiff1d(np.arange(len(head.faces)), rest))
    region = trimesh.Trimesh(head.vertices, head.faces[region_faces], process=False)
    region.remove_unreferenced_vertices()
    if tidy_boundary:
        region = without_bowties(region)
    loops = boundary_loops(region)
    if len(loops) != 1:
        raise StitchError(f"{pinna_source}: the head's own pinna region has {len(loops)} boundary loops instead of one "
                          "(the head is not a single surface under the pinna's rim)")
    return region


def replace_pinna(head: trimesh.Trimesh, pinna: trimesh.Trimesh, *, gap_mm: float = 1.5, reach_mm: float = 25.0,
                  head_source: str = "head mesh", pinna_source: str = "pinna mesh") -> StitchedHead:
    """Cut the head's left pinna region and stitch ``pinna`` in (both in mm, same frame)."""
    problems = mesh_problems(head.vertices, head.faces)
    if problems:
        raise StitchError(f"{head_source}: the head cannot be stitched:\n  - " + "\n  - ".join(problems))
    rim = _check_pinna(pinna, pinna_source)
    rim_points = np.asarray(pinna.vertices)[rim]
    head_tree = trimesh.proximity.ProximityQuery(head)
    rim_distance = np.abs(head_tree.signed_distance(rim_points))
    if np.median(rim_distance) > 4.0:
        raise StitchError(f"{pinna_source}: the rim of the pinna lies {np.median(rim_distance):.1f} mm (median) from "
                          f"the skin of {head_source}; it must rest on the head (align the pinna to this head's "
                          "left ear, in the same frame)")

    covered, centre, plane = _covered_by_pinna(head, pinna, rim, gap_mm, reach_mm)
    cut = covered[head.faces].any(axis=1)
    if not cut.any():
        raise StitchError(f"{pinna_source}: no head face lies under the pinna; is it placed at this head's left ear?")

    kept = trimesh.Trimesh(head.vertices, head.faces[~cut], process=False)
    components = trimesh.graph.connected_components(kept.face_adjacency, nodes=np.arange(len(kept.faces)))
    largest = max(components, key=len)
    kept_faces = kept.faces[np.sort(largest)]
    kept = trimesh.Trimesh(head.vertices, kept_faces, process=False)
    holes = boundary_loops(kept)
    if len(holes) != 1:
        pieces = _components(head, np.flatnonzero(cut))
        sizes = ", ".join(f"{len(p):,}" for p in sorted(pieces, key=len, reverse=True))
        raise StitchError(f"{head_source}: cutting under the pinna left {len(holes)} holes instead of one: the head "
                          f"under the rim of {pinna_source} falls into {len(pieces)} pieces ({sizes} faces), the "
                          f"rim spanning z {rim_points[:, 2].min():.1f} to {rim_points[:, 2].max():.1f} mm; the pinna "
                          "rim does not enclose one simple region of the head (check its placement)")
    offset = len(head.vertices)
    vertices = np.vstack([head.vertices, pinna.vertices])
    strip = bridge_loops(vertices, holes[0], rim + offset, metric=(vertices - centre) @ plane)
    faces = np.vstack([kept_faces, pinna.faces + offset, strip])
    origin = np.concatenate([np.zeros(len(kept_faces), np.int8), np.ones(len(pinna.faces), np.int8),
                             np.full(len(strip), 2, np.int8)])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.remove_unreferenced_vertices()
    if not mesh.is_winding_consistent:
        raise StitchError(f"{pinna_source}: the pinna's triangles are wound against the head's; its normals must "
                          "point out of the head (flip the pinna's faces)")
    if mesh.volume <= 0:
        raise StitchError(f"{head_source}: the stitched head has inward normals (negative volume)")
    gap = float(np.median(cKDTree(vertices[holes[0]]).query(rim_points)[0]))
    return StitchedHead(mesh, origin, int(cut.sum()), gap)
