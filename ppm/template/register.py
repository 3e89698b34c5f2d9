"""Rigid and non-rigid registration of a template surface onto a scanned pinna (millimetres).

Rigid: iterative closest point (trimesh). Non-rigid: optimal-step non-rigid ICP of Amberg et al.
(2007) as implemented by `trimesh.registration.nricp_amberg`, with a stiffness schedule that goes
from nearly rigid to supple, so the template's folds slide onto the scan's folds.
"""
from __future__ import annotations

import numpy as np
import trimesh
from trimesh.registration import icp, nricp_amberg, procrustes

#: (stiffness, landmark weight, normal weight, max iterations) per stage, stiff to supple (mm data).
NRICP_STEPS = ((0.05, 0.0, 0.5, 10), (0.02, 0.0, 0.5, 10), (0.007, 0.0, 0.5, 10), (0.002, 0.0, 0.5, 10))
#: Correspondences farther than this (mm) are ignored by the non-rigid ICP.
NRICP_MAX_DISTANCE_MM = 6.0


def rigid_align(source_mm: np.ndarray, target: trimesh.Trimesh, iterations: int = 60) -> np.ndarray:
    """(4, 4) rigid transform that moves the points `source_mm` onto the surface `target` (ICP)."""
    matrix, _, _ = icp(source_mm, target, initial=np.eye(4), threshold=1e-6, max_iterations=iterations,
                       reflection=False, scale=False)
    return matrix


def register_onto(source: trimesh.Trimesh, target: trimesh.Trimesh,
                  steps: tuple[tuple[float, float, float, int], ...] = NRICP_STEPS) -> np.ndarray:
    """Vertices (n, 3) of `source` moved rigidly (:func:`rigid_align`), then non-rigidly with `steps`
    (:func:`nonrigid_register`) onto the surface `target` (same vertex order, mm)."""
    matrix = rigid_align(source.vertices, target)
    moved = trimesh.Trimesh(trimesh.transform_points(source.vertices, matrix), source.faces, process=False)
    return nonrigid_register(moved, target, steps)


def nonrigid_register(source: trimesh.Trimesh, target: trimesh.Trimesh,
                      steps: tuple[tuple[float, float, float, int], ...] = NRICP_STEPS) -> np.ndarray:
    """Vertices (n, 3) of `source` deformed onto `target` by non-rigid ICP (same vertex order, mm), with the
    stiffness schedule `steps` (see NRICP_STEPS)."""
    return np.asarray(
        nricp_amberg(source, target, steps=steps, distance_threshold=NRICP_MAX_DISTANCE_MM,
                     use_faces=True, use_vertex_normals=True)
    )


def procrustes_mean(shapes_mm: list[np.ndarray], iterations: int = 5) -> np.ndarray:
    """Generalised Procrustes mean (rotation + translation, no scale) of shapes in correspondence.

    The mean is expressed in the pose of the average of the input poses (close to the first shape's
    frame); every shape is (n, 3) in mm with the same vertex order.
    """
    mean = np.mean(shapes_mm, axis=0)
    for _ in range(iterations):
        aligned = [procrustes(shape, mean, reflection=False, scale=False)[1] for shape in shapes_mm]
        mean = np.mean(aligned, axis=0)
    return mean
