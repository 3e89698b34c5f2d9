"""Rigid transforms <-> the parent bone's location and rotation (millimetres, degrees, Euler 'ZYX').

The parent bone `Size-Bendy` points +y with roll 0, so its pose frame is the project frame and its
pose maps a template point x to  head + t + R S (x - head),  with R = Rx(a) Ry(b) Rz(c) for Blender's
rotation mode 'ZYX' (Z applied first) and S the diagonal of the scales.
"""
from __future__ import annotations

import numpy as np
import trimesh


def rotation_zyx(angles_deg: np.ndarray) -> np.ndarray:
    """(3, 3) rotation for Euler angles (X, Y, Z) in degrees, Blender mode 'ZYX': R = Rx Ry Rz."""
    ax, ay, az = np.deg2rad(np.asarray(angles_deg, dtype=np.float64))
    rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    return rx @ ry @ rz


def euler_zyx_deg(rotation: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rotation_zyx`: Euler angles (X, Y, Z) in degrees of a (3, 3) rotation."""
    r = np.asarray(rotation, dtype=np.float64)
    ay = np.arcsin(np.clip(r[0, 2], -1.0, 1.0))
    ax = np.arctan2(-r[1, 2], r[2, 2])
    az = np.arctan2(-r[0, 1], r[0, 0])
    return np.rad2deg([ax, ay, az])


def parent_pose_from_rigid(matrix: np.ndarray, head_mm: np.ndarray) -> dict[str, float]:
    """Parent-bone location (mm) and rotation (deg) that reproduce the rigid (4, 4) `matrix`."""
    rotation, translation = matrix[:3, :3], matrix[:3, 3]
    head = np.asarray(head_mm, dtype=np.float64)
    location = rotation @ head + translation - head  # head + t + R (x - head) == R x + translation
    angles = euler_zyx_deg(rotation)
    values = {f"Location_Size-Bendy_{a}": float(v) for a, v in zip("XYZ", location)}
    values.update({f"Rotation_Size-Bendy_{a}": float(v) for a, v in zip("XYZ", angles)})
    return values


def apply_similarity(mesh: trimesh.Trimesh, matrix: np.ndarray) -> trimesh.Trimesh:
    """The mesh moved by a (4, 4) similarity (rotation, uniform scale, offset, possibly a reflection); a
    reflection flips the faces so that the normals stay outward."""
    vertices = trimesh.transform_points(mesh.vertices, matrix)
    faces = mesh.faces[:, ::-1] if np.linalg.det(matrix[:3, :3]) < 0 else mesh.faces
    return trimesh.Trimesh(vertices, np.ascontiguousarray(faces), process=False)
