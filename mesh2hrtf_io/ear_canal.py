"""The ear-canal entrance element(s) that act as the reciprocal source of a BEM head mesh.

Used by the stitch (:mod:`stitching.pipeline`) and by the export (:mod:`mesh2hrtf_io.hrtf_job`): one rule for
both, so that the source of a stitched head is the source its project is solved with.

Frame: millimetres, +x front, +y left, +z up, origin at the interaural centre. A ray from the
interaural centre along +y (left) or -y (right) leaves the head at the ear: its first exit point lies
in the concha near the canal, often on the wall behind the tragus. From there the surface is followed
downhill (towards the interaural centre) to the bottom of the pit it leads into: the blocked ear
canal, which a scan closes with a flat patch where it could not see in (SONICOM heads: 65-82 mm², 1-7 mm
below the ray's exit). The faces nearest the middle of that floor (at least ``min_area_mm2``) are the
source. Where no such pit lies within ``pit_radius_mm`` of the exit (a sphere, a smooth dummy head) the
faces at the exit are the source.

Where the source sits matters: at 14.4 kHz, sources 4-8 mm apart in one concha give directional
transfer functions that differ by 2-6 dB (median over 793 directions, SONICOM P143, NumCalc).
"""
from __future__ import annotations

import numpy as np
import trimesh


from .errors import Mesh2HrtfIoError

SIDES = {"left": 1.0, "right": -1.0}


class EarCanalError(Mesh2HrtfIoError):
    """No usable ear-canal element: the head is not centred at the interaural axis or has no ear there.

    Lives here, below both the stitch (which places the source while it builds the head) and the export (which
    finds it again on a given head); a :class:`core.errors.PipelineError` like every stage's error."""


def ear_canal_elements(mesh: trimesh.Trimesh, side: str, min_area_mm2: float = 4.0,
                       source: str = "head mesh", pit_radius_mm: float = 12.0,
                       floor_depth_mm: float = 1.5) -> np.ndarray:
    """Face indices of the ear-canal entrance on ``side`` ('left' or 'right'), at least ``min_area_mm2``:
    the middle of the canal floor the ray exit leads down into, or the exit itself (see the module)."""
    centre = ear_canal_centre(mesh, side, source, pit_radius_mm, floor_depth_mm)
    return faces_around(mesh, centre, np.array([0.0, SIDES[side], 0.0]), min_area_mm2)


def ear_canal_centre(mesh: trimesh.Trimesh, side: str, source: str = "head mesh", pit_radius_mm: float = 12.0,
                     floor_depth_mm: float = 1.5, require_floor: bool = False) -> np.ndarray:
    """The point (mm) the source on ``side`` is centred on: the middle (area-weighted) of the canal floor the ray
    exit leads down into, or the exit itself where there is no pit (see the module; with ``require_floor`` that
    is an :class:`EarCanalError`). The head frame of a new listener (:mod:`listener.head_frame`) puts its
    interaural axis through the two."""
    if side not in SIDES:
        raise EarCanalError(f"side must be 'left' or 'right', got {side!r}")
    direction = np.array([0.0, SIDES[side], 0.0])
    hit, face = _ray_exit(mesh, direction, side, source)
    floor = canal_floor(mesh, hit, face, direction, pit_radius_mm, floor_depth_mm)
    if floor is None:
        if require_floor:
            raise EarCanalError(f"{source}: no canal pit within {pit_radius_mm:g} mm of where the {side} ear axis "
                                "leaves the head")
        return hit
    weights = mesh.area_faces[floor]
    return (mesh.triangles_center[floor] * weights[:, None]).sum(axis=0) / weights.sum()


def faces_around(mesh: trimesh.Trimesh, point_mm: np.ndarray, direction: np.ndarray,
                 min_area_mm2: float) -> np.ndarray:
    """The outward-facing faces (normal along ``direction``) whose centres lie nearest ``point_mm``, as few as
    reach ``min_area_mm2`` together; sorted face indices."""
    outward = np.flatnonzero(mesh.face_normals @ direction > 0.0)
    order = outward[np.argsort(np.linalg.norm(mesh.triangles_center[outward] - point_mm, axis=1))]
    count = int(np.searchsorted(np.cumsum(mesh.area_faces[order]), min_area_mm2)) + 1
    return np.sort(order[:count]).astype(np.int64)


def _ray_exit(mesh: trimesh.Trimesh, direction: np.ndarray, side: str, source: str) -> tuple[np.ndarray, int]:
    """Where a ray from the origin along ``direction`` first leaves the head (mm) and the face it leaves by."""
    locations, _, faces = mesh.ray.intersects_location([[0.0, 0.0, 0.0]], [direction])
    if len(faces) == 0:
        raise EarCanalError(f"{source}: a ray from the origin along {direction[1]:+.0f}·y leaves no surface; the head "
                            "must be in the project frame (origin at the interaural centre, +y left, millimetres)")
    first = int(np.argmin(np.linalg.norm(locations, axis=1)))
    hit, face = locations[first], int(faces[first])
    depth = abs(float(hit[1]))
    if not 40.0 <= depth <= 110.0:
        raise EarCanalError(f"{source}: the {side} ear canal was found {depth:.1f} mm from the interaural centre; "
                            "expected 40-110 mm: check the units (millimetres) and that the origin is the "
                            "interaural centre")
    if float(mesh.face_normals[face] @ direction) <= 0.0:
        raise EarCanalError(f"{source}: the {side} ear element faces inwards; fix the normals (outward) first")
    return hit, face


def canal_floor(mesh: trimesh.Trimesh, hit: np.ndarray, face: int, direction: np.ndarray,
                pit_radius_mm: float = 12.0, floor_depth_mm: float = 1.5) -> np.ndarray | None:
    """Faces of the pit floor that the surface leads down into from ``hit`` (on ``face``): from the face's
    deepest corner, step to the deepest neighbour while it lies deeper (along ``direction``, mm), within
    ``pit_radius_mm`` of the hit across the ear axis. If the walk stops inside that radius (a pit), the
    floor is every face within ``floor_depth_mm`` of the bottom's depth, edge-connected to it, facing out
    (normal within 60° of the ear axis). None when the walk reaches the radius (no pit: the exit is kept)."""
    vertices = np.asarray(mesh.vertices)
    lateral = vertices @ direction
    across = vertices - hit - np.outer(lateral - hit @ direction, direction)
    reach = np.linalg.norm(across, axis=1)
    neighbours = mesh.vertex_neighbors
    corners = mesh.faces[face]
    current = int(corners[np.argmin(lateral[corners])])
    while True:
        options = [n for n in neighbours[current] if reach[n] < pit_radius_mm]
        deeper = min(options, key=lambda n: lateral[n], default=current)
        if lateral[deeper] >= lateral[current]:
            break
        current = int(deeper)
    if reach[current] > pit_radius_mm - 2.0:
        return None
    face_lateral = lateral[mesh.faces].max(axis=1)
    face_reach = reach[mesh.faces].max(axis=1)
    candidate = (face_lateral < lateral[current] + floor_depth_mm) & (face_reach < pit_radius_mm) & \
                (mesh.face_normals @ direction > 0.5)
    ids = np.flatnonzero(candidate)
    if len(ids) == 0:
        return None
    part = trimesh.Trimesh(vertices, mesh.faces[ids], process=False)
    components = trimesh.graph.connected_components(part.face_adjacency, nodes=np.arange(len(ids)))
    at_bottom = [c for c in components if np.isin(mesh.faces[ids[c]], current).any()]
    return np.sort(ids[at_bottom[0]]) if at_bottom else None
