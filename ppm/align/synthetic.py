"""Synthetic scans made by the PPM itself, with scan-like defects, where the true parameters are known.

A random ear (parameters drawn within the typical spread between listeners, inside the bounds) poses
the template; the surface gets Gaussian noise along the normals, a few holes (geodesic discs of missing
triangles) and a share of outlier vertices thrown off the surface. Millimetres, project frame.
"""
from __future__ import annotations

import numpy as np
import trimesh

from ..geodesic import distance_from, edge_graph
from ..model import PinnaModel
from ..parameters import PinnaParameters, random_parameters
from .target import Target, target_from_mesh


def add_scan_defects(mesh: trimesh.Trimesh, rng: np.random.Generator, *, noise_mm: float = 0.2, holes: int = 3,
                     hole_radius_mm: float = 4.0, outlier_share: float = 0.02,
                     hole_centres: np.ndarray | None = None) -> trimesh.Trimesh:
    """A copy of ``mesh`` (mm) as a scanner would deliver it: Gaussian noise of ``noise_mm`` along the
    normals, ``holes`` geodesic discs of missing triangles (centred on vertices drawn from
    ``hole_centres``, default any vertex) and a share of outlier vertices thrown 2-8 mm off the surface."""
    vertices = mesh.vertices + rng.normal(0.0, noise_mm, (len(mesh.vertices), 1)) * mesh.vertex_normals
    faces = mesh.faces
    if holes:
        graph = edge_graph(mesh.vertices, faces)
        pool = np.arange(len(vertices)) if hole_centres is None else np.asarray(hole_centres)
        centres = rng.choice(pool, holes, replace=False)
        missing = distance_from(graph, centres) < hole_radius_mm
        faces = faces[~missing[faces].any(axis=1)]
    outliers = rng.random(len(vertices)) < outlier_share
    directions = rng.normal(size=(int(outliers.sum()), 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    vertices[outliers] += directions * rng.uniform(2.0, 8.0, (int(outliers.sum()), 1))
    scan = trimesh.Trimesh(vertices, faces, process=False)
    scan.remove_unreferenced_vertices()
    return scan


def synthetic_scan(model: PinnaModel, rng: np.random.Generator, *, fraction: float = 0.5, noise_mm: float = 0.2,
                   holes: int = 3, hole_radius_mm: float = 4.0, outlier_share: float = 0.02,
                   params: PinnaParameters | None = None) -> tuple[Target, PinnaParameters]:
    """A defective scan of the PPM posed with random parameters (within `fraction` of each typical range).

    Returns the target and the true parameters.
    """
    truth = params if params is not None else random_parameters(rng, fraction)
    scan = add_scan_defects(model.mesh(truth), rng, noise_mm=noise_mm, holes=holes, hole_radius_mm=hole_radius_mm,
                            outlier_share=outlier_share)
    return target_from_mesh(scan, "synthetic PPM scan"), truth
