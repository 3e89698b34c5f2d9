"""A defective ear scan made watertight by a standard tool: MeshLab's outlier selection and screened Poisson
surface reconstruction (through pymeshlab), then trimmed where the surface lies far from every scan point
(millimetres, head frame: +x front, +y left, +z up).

It is what a careful user does before putting a scan on a head, and the baseline the PPM must beat from a
defective scan (the ``scan_hard`` condition; ``poisson`` in ``benchmarks/align_defects.py``). The settings
live in ``stitching/data/scan_reconstruction.yaml``.
"""
from __future__ import annotations

import dataclasses
import logging
from functools import lru_cache
from importlib import resources
from typing import TYPE_CHECKING

import numpy as np
import trimesh
import yaml
from scipy.spatial import cKDTree

from .errors import StitchError

if TYPE_CHECKING:  # the layer's types, for the hints only
    from ppm.align.detail import DetailSettings
    from ppm.align.target import Target

log = logging.getLogger(__name__)


@lru_cache(maxsize=1)
def reconstruction_settings() -> dict:
    """The parsed ``stitching/data/scan_reconstruction.yaml``."""
    text = resources.files("stitching").joinpath("data/scan_reconstruction.yaml").read_text(encoding="utf-8")
    return yaml.safe_load(text)


@dataclasses.dataclass(frozen=True)
class Reconstruction:
    """The watertight reconstruction of a scan, untrimmed (``closed``) and trimmed (``surface``), in mm, with
    how many scan vertices the outlier selection deleted."""

    closed: trimesh.Trimesh
    surface: trimesh.Trimesh
    outliers_removed: int
    scan_vertices: int

    def report(self) -> dict:
        return {"scan_vertices": self.scan_vertices, "outliers_removed": self.outliers_removed,
                "poisson_faces": int(len(self.closed.faces)), "trimmed_faces": int(len(self.surface.faces)),
                "trimmed_area_mm2": round(float(self.surface.area), 1)}


def _check_scan(scan: trimesh.Trimesh, source: str) -> None:
    vertices = np.asarray(scan.vertices)
    if len(vertices) < 100 or len(scan.faces) == 0:
        raise StitchError(f"{source}: {len(vertices)} vertices and {len(scan.faces)} triangles are too few for a "
                          "surface reconstruction; give the scan as a triangle mesh (PLY/STL/OBJ) in mm")
    if not np.isfinite(vertices).all():
        raise StitchError(f"{source}: the scan holds NaN or inf coordinates; drop those vertices first")
    extent = float(np.linalg.norm(np.ptp(vertices, axis=0)))
    if not 20.0 <= extent <= 400.0:
        raise StitchError(f"{source}: the scan is {extent:.3g} units across; an ear crop is 50-200 mm: give it in "
                          "millimetres (a scan in metres must be scaled by 1000)")


def poisson_surface(scan: trimesh.Trimesh, settings: dict | None = None, source: str = "scan") -> Reconstruction:
    """Outlier removal and screened Poisson reconstruction of ``scan`` (a triangle mesh in mm), then the trim
    of ``settings["trim_mm"]`` (default: :func:`reconstruction_settings`). Import bpy before this in a process
    that uses both (pymeshlab ships an older Embree)."""
    import pymeshlab  # noqa: PLC0415

    settings = settings or reconstruction_settings()
    _check_scan(scan, source)
    meshes = pymeshlab.MeshSet()
    meshes.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(scan.vertices, np.float64),
                                   face_matrix=np.asarray(scan.faces, np.int32)))
    outliers = settings["outliers"]
    meshes.compute_selection_point_cloud_outliers(propthreshold=float(outliers["probability_threshold"]),
                                                  knearest=int(outliers["k_nearest"]))
    removed = int(meshes.current_mesh().selected_vertex_number())
    meshes.meshing_remove_selected_vertices()
    meshes.meshing_remove_unreferenced_vertices()
    kept = np.array(meshes.current_mesh().vertex_matrix())
    meshes.compute_normal_per_vertex()
    poisson = settings["poisson"]
    meshes.generate_surface_reconstruction_screened_poisson(depth=int(poisson["depth"]),
                                                            preclean=bool(poisson["preclean"]))
    result = meshes.current_mesh()
    closed = trimesh.Trimesh(np.array(result.vertex_matrix()), np.array(result.face_matrix()), process=False)
    if len(closed.faces) == 0:
        raise StitchError(f"{source}: screened Poisson reconstruction gave no surface (too few points with normals)")
    return Reconstruction(closed, trimmed_near(closed, kept, float(settings["trim_mm"]), source), removed,
                          int(len(scan.vertices)))


def trimmed_near(surface: trimesh.Trimesh, points: np.ndarray, trim_mm: float, source: str = "scan") -> trimesh.Trimesh:
    """``surface`` without the faces whose centre lies farther than ``trim_mm`` from every point of ``points``
    (mm), its largest edge-connected piece."""
    distance = cKDTree(np.asarray(points)).query(surface.triangles_center)[0]
    near = np.flatnonzero(distance <= trim_mm)
    if near.size == 0:
        raise StitchError(f"{source}: no reconstructed face lies within {trim_mm} mm of a scan point")
    part = trimesh.Trimesh(surface.vertices, surface.faces[near], process=False)
    pieces = trimesh.graph.connected_components(part.face_adjacency, nodes=np.arange(len(near)))
    largest = np.sort(max(pieces, key=len))
    out = trimesh.Trimesh(surface.vertices, surface.faces[near[largest]], process=False)
    out.remove_unreferenced_vertices()
    return out


def enclosed_by(scan_points: cKDTree, centres_mm: np.ndarray, normals: np.ndarray, radius_mm: float,
                open_angle_deg: float) -> np.ndarray:
    """Per centre (mm, with its unit normal), whether the points of ``scan_points`` (a KD-tree of the scan's
    vertices, mm) within ``radius_mm`` surround it in its tangent plane: no angular gap between them wider than
    ``open_angle_deg`` as seen from the centre. A hole in a scan is surrounded by scan; what a reconstruction adds
    beyond the scan's outer edge (where it balloons round the crop) has scan on one side only."""
    points = scan_points.data
    out = np.zeros(len(centres_mm), dtype=bool)
    for index, group in enumerate(scan_points.query_ball_point(np.asarray(centres_mm, np.float64), radius_mm)):
        if len(group) < 3:
            continue
        offsets = points[group] - centres_mm[index]
        normal = normals[index]
        in_plane = offsets - np.outer(offsets @ normal, normal)
        axis = in_plane[np.argmax(np.linalg.norm(in_plane, axis=1))]
        axis = axis / max(float(np.linalg.norm(axis)), 1e-12)
        angles = np.sort(np.arctan2(in_plane @ np.cross(normal, axis), in_plane @ axis))
        gaps = np.diff(np.r_[angles, angles[0] + 2.0 * np.pi])
        out[index] = np.degrees(gaps.max()) <= open_angle_deg
    return out


def hole_fill(scan: trimesh.Trimesh, beyond_mm: float, settings: dict | None = None,
              source: str = "scan") -> trimesh.Trimesh:
    """The screened Poisson reconstruction's fill of the holes of ``scan`` (a triangle mesh in mm): the faces of
    its trimmed surface (:func:`poisson_surface`) whose centre lies farther than ``beyond_mm`` from every scan
    vertex, where the scan itself says nothing, and that the scan surrounds (:func:`enclosed_by`, the ``fill``
    settings of stitching/data/scan_reconstruction.yaml): a hole's fill, not the balloon round the crop's edge.
    May be empty (a scan without holes)."""
    settings = settings or reconstruction_settings()
    surface = poisson_surface(scan, settings, source).surface
    scan_points = cKDTree(np.asarray(scan.vertices, np.float64))
    far = np.flatnonzero(scan_points.query(surface.triangles_center)[0] > beyond_mm)
    enclosed = enclosed_by(scan_points, surface.triangles_center[far], surface.face_normals[far],
                           float(settings["fill"]["surround_radius_mm"]), float(settings["fill"]["open_angle_deg"]))
    fill = trimesh.Trimesh(surface.vertices, surface.faces[far[enclosed]], process=False)
    fill.remove_unreferenced_vertices()
    return fill


def layer_evidence(scan: Target, detail_settings: DetailSettings) -> Target:
    """The personal-detail layer's evidence from a prepared scan (``ppm.align.target.Target``, mm, project frame):
    the scan itself, joined with its reconstruction's fill of its holes (:func:`hole_fill`) where the layer's
    ``hole_fill_mm`` setting asks for it (ppm/data/personal_detail.yaml), so that the raw points speak where there
    are any and the fill only where there are none. Import bpy before this in a process that uses both."""
    from ppm.align.detail import joined_evidence  # noqa: PLC0415

    if detail_settings.hole_fill_mm is None:
        return scan
    try:
        fill = hole_fill(scan.mesh, float(detail_settings.hole_fill_mm), source=scan.source)
    except StitchError as error:  # the fill is extra evidence: without it the layer still has the scan
        log.warning("%s: no reconstruction's fill for the personal-detail layer (%s); the scan alone is its "
                    "evidence", scan.source, error)
        return dataclasses.replace(scan, warnings=scan.warnings + (f"no hole fill: {error}",))
    joined = joined_evidence(scan, fill)
    if detail_settings.noise_stiffness_factor is None and detail_settings.outlier_sigmas is None:
        return joined
    from ppm.align.scan_noise import scan_noise_mm  # noqa: PLC0415

    # the schedule's floor and the stray-point test ask for the scan's own noise, not the smooth fill's
    return dataclasses.replace(joined, noise_mm=scan_noise_mm(scan.mesh.vertices))
