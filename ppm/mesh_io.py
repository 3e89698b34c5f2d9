"""Loading, checking and writing pinna meshes (millimetres, project frame: +x front, +y left, +z up).

Every loader checks what a user can get wrong: a missing, empty or corrupt file, non-triangle or
non-finite data, a mesh in metres instead of millimetres, and a right ear where a left is expected.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh

from core.atomic import atomic_path
from .constants import MAX_PINNA_EXTENT_MM, MIN_PINNA_EXTENT_MM
from .errors import PpmError

MESH_SUFFIXES = (".ply", ".stl", ".obj")


def load_mesh(path: str | os.PathLike, *, process: bool = False) -> trimesh.Trimesh:
    """Read a triangle mesh (PLY, STL or OBJ) and check that it is usable.

    Parameters
    ----------
    path : path-like
        Mesh file in millimetres.
    process : bool
        Let trimesh merge duplicate vertices (changes the vertex order).

    Raises
    ------
    PpmError
        If the file is missing, empty, not a mesh, holds no triangles, or holds NaN/inf values.
    """
    path = Path(path)
    if not path.is_file():
        raise PpmError(f"{path}: no such mesh file; give the path of a PLY, STL or OBJ file")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise PpmError(f"{path}: unsupported mesh format {path.suffix!r}; use one of {MESH_SUFFIXES}")
    if path.stat().st_size == 0:
        raise PpmError(f"{path}: the file is empty; re-export the mesh")
    try:
        mesh = trimesh.load(path, force="mesh", process=process)
    except Exception as exc:  # trimesh raises many types for corrupt files
        raise PpmError(f"{path}: cannot be read as a mesh ({exc}); re-export it as binary PLY") from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise PpmError(f"{path}: holds no triangles; a surface mesh is needed, not a point cloud")
    check_vertices(mesh.vertices, source=str(path))
    return mesh


def check_vertices(vertices_mm: np.ndarray, *, source: str = "mesh") -> np.ndarray:
    """Return `vertices_mm` as (n, 3) float64 after checking shape and finiteness.

    Raises
    ------
    PpmError
        If the array is not (n, 3) or holds NaN or inf.
    """
    vertices_mm = np.asarray(vertices_mm, dtype=np.float64)
    if vertices_mm.ndim != 2 or vertices_mm.shape[1] != 3:
        raise PpmError(f"{source}: vertices must be an (n, 3) array, got shape {vertices_mm.shape}")
    bad = ~np.isfinite(vertices_mm).all(axis=1)
    if bad.any():
        raise PpmError(
            f"{source}: {int(bad.sum())} vertices hold NaN or inf (first index {int(np.flatnonzero(bad)[0])}); "
            "remove them before fitting"
        )
    return vertices_mm


def check_units_mm(vertices_mm: np.ndarray, *, source: str = "mesh") -> None:
    """Check that a pinna-sized mesh is in millimetres.

    Raises
    ------
    PpmError
        If its bounding-box diagonal is implausible for a pinna in mm (metres or micrometres).
    """
    extent = float(np.linalg.norm(np.ptp(vertices_mm, axis=0)))
    if extent < MIN_PINNA_EXTENT_MM:
        raise PpmError(
            f"{source}: the mesh is only {extent:.4g} units across; a pinna is about 60 mm, so this mesh "
            "is probably in metres: scale it by 1000 to millimetres"
        )
    if extent > MAX_PINNA_EXTENT_MM:
        raise PpmError(
            f"{source}: the mesh is {extent:.4g} units across; a pinna crop is under {MAX_PINNA_EXTENT_MM:g} mm, "
            "so this mesh is probably in micrometres or not a pinna crop: scale it to millimetres or crop it"
        )


def check_left_side(mesh: trimesh.Trimesh, *, source: str = "mesh") -> None:
    """Check that a pinna crop is a LEFT ear in the project frame (+y left).

    A left pinna lies at +y and its outer surface faces +y (area-weighted mean normal).

    Raises
    ------
    PpmError
        If the mesh lies at -y or faces -y (a right ear, or a left ear not in the project frame).
    """
    centre_y = float(np.average(mesh.triangles_center[:, 1], weights=mesh.area_faces))
    normal_y = float((mesh.face_normals[:, 1] * mesh.area_faces).sum() / mesh.area.sum())
    if centre_y < 0:
        raise PpmError(
            f"{source}: the pinna lies at y = {centre_y:.1f} mm (< 0), which is a RIGHT ear in the project frame "
            "(+y left); mirror it with y -> -y (and flip the faces) or ask for side='right'"
        )
    if normal_y < 0:
        raise PpmError(
            f"{source}: the surface faces -y (mean normal y = {normal_y:.2f}); a left pinna faces +y. The mesh is "
            "either a mirrored copy without flipped faces or has inward normals: flip its faces"
        )


def mirror_right_to_left(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Mirror a right pinna (y -> -y) into a left one, flipping the faces to keep normals outward."""
    vertices = mesh.vertices * np.array([1.0, -1.0, 1.0])
    return trimesh.Trimesh(vertices, mesh.faces[:, ::-1].copy(), process=False)


def load_left_pinna(path: str | os.PathLike, side: str = "left") -> trimesh.Trimesh:
    """Load a pinna crop as a LEFT ear in millimetres, mirroring a right ear when `side='right'`.

    Raises
    ------
    PpmError
        On any problem of :func:`load_mesh`, wrong units, or a side that does not match `side`.
    """
    if side not in ("left", "right"):
        raise PpmError(f"side must be 'left' or 'right', got {side!r}")
    mesh = load_mesh(path)
    check_units_mm(mesh.vertices, source=str(path))
    if side == "right":
        centre_y = float(mesh.vertices[:, 1].mean())
        if centre_y > 0:
            raise PpmError(f"{path}: side='right' was given but the pinna lies at +y = {centre_y:.1f} mm (a left ear)")
        mesh = mirror_right_to_left(mesh)
    check_left_side(mesh, source=str(path))
    return mesh


def write_mesh(path: str | os.PathLike, vertices_mm: np.ndarray, faces: np.ndarray) -> Path:
    """Write a mesh atomically (PLY/STL/OBJ from the suffix), vertex order kept, in millimetres."""
    path = Path(path)
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise PpmError(f"{path}: unsupported mesh format {path.suffix!r}; use one of {MESH_SUFFIXES}")
    mesh = trimesh.Trimesh(check_vertices(vertices_mm, source=str(path)), np.asarray(faces, np.int64), process=False)
    with atomic_path(path) as tmp:
        mesh.export(tmp, file_type=path.suffix.lower().lstrip("."))
    return path
