"""Preparation of a scanned pinna as an alignment target (millimetres, project frame).

Checks (via `ppm.mesh_io`): file readable and not empty, triangles, no NaN, millimetres, left ear
(a right ear is mirrored on request). Then: the pinna plus a ring of skin is cut out of the crop
(`ppm.template.segment`), isolated outlier points are removed (statistical distance to their
neighbours), and the share of the pinna surface missing to holes is estimated so a badly
incomplete scan is flagged instead of silently fitted.
"""
from __future__ import annotations

import dataclasses
import logging
import os

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ..errors import PpmError
from ..mesh_io import load_left_pinna
from ..template.segment import crop_to_region, pinna_region

log = logging.getLogger(__name__)

#: A scan point farther from its neighbours than this many median spacings is an outlier.
OUTLIER_SPACING_FACTOR = 6.0
#: Warn when more than this share of the expected pinna surface is missing.
MAX_HOLE_SHARE = 0.25


@dataclasses.dataclass(frozen=True)
class Target:
    """A prepared pinna scan.

    points_mm : (n, 3) float
        Target points (the scan's pinna-region vertices, outliers removed), mm, project frame.
    normals : (n, 3) float
        Unit outward normals at the points.
    mesh : trimesh.Trimesh
        The pinna-region surface of the scan.
    source : str
        Where it came from.
    warnings : tuple of str
        Problems found that did not stop the preparation (they go into the fit's summary).
    pose : dict or None
        For a scan given in any pose: how it was brought into the project frame (unit, mirrored, the
        (4, 4) similarity scan -> project frame as nested lists, confidence); None for a project-frame scan.
    scan : trimesh.Trimesh or None
        The whole scan the pinna region was cut from, in the same frame (mm, project frame, left ear): what
        :mod:`ppm.align.widen` fits again on when the segmentation left out part of the pinna. None when not kept.
    noise_mm : float or None
        The scan's own noise (:func:`ppm.align.scan_noise.scan_noise_mm`, mm) where the surface holds more than the
        scan (the personal-detail layer's evidence joined with a reconstruction's fill); None: judge it from ``mesh``.
    """

    points_mm: np.ndarray
    normals: np.ndarray
    mesh: trimesh.Trimesh
    source: str
    warnings: tuple[str, ...] = ()
    pose: dict | None = None
    scan: trimesh.Trimesh | None = None
    noise_mm: float | None = None


def remove_outliers(points_mm: np.ndarray, neighbours: int = 8) -> np.ndarray:
    """Boolean mask of the points to keep: mean distance to `neighbours` nearest points is not
    more than OUTLIER_SPACING_FACTOR times the median of that distance."""
    tree = cKDTree(points_mm)
    distance, _ = tree.query(points_mm, k=neighbours + 1)
    spacing = distance[:, 1:].mean(axis=1)
    return spacing <= OUTLIER_SPACING_FACTOR * np.median(spacing)


def surface_without_outliers(target: Target) -> trimesh.Trimesh:
    """The prepared scan's surface without the faces of its outlier vertices (:func:`remove_outliers`: the points a
    PPM fit ignores too), mm, project frame."""
    mesh = target.mesh
    if mesh is None or len(mesh.faces) == 0:
        raise PpmError(f"{target.source}: this needs the scan's surface, not points only")
    return crop_to_region(mesh, remove_outliers(np.asarray(mesh.vertices)))


def hole_share(mesh: trimesh.Trimesh) -> float:
    """Estimated share of the surface missing to holes: the area that closing the inner boundary
    loops (all but the longest, outer one) would add, relative to the whole. Each hole's area is
    the magnitude of its loop's vector area."""
    import networkx as nx

    edges = mesh.edges_sorted[trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)]
    if len(edges) == 0:
        return 0.0
    loops = nx.cycle_basis(nx.from_edgelist(edges.tolist()))
    if len(loops) < 2:
        return 0.0
    areas, lengths = [], []
    for loop in loops:
        ring = mesh.vertices[loop]
        following = np.roll(ring, -1, axis=0)
        areas.append(0.5 * np.linalg.norm(np.cross(ring, following).sum(axis=0)))
        lengths.append(np.linalg.norm(following - ring, axis=1).sum())
    outer = int(np.argmax(lengths))
    missing = float(sum(a for i, a in enumerate(areas) if i != outer))
    return missing / (missing + float(mesh.area))


def prepare_target(path: str | os.PathLike, side: str = "left", margin_mm: float = 3.0,
                   segment: bool = True, scan_pose: str = "project_frame") -> Target:
    """Load and prepare a pinna scan for alignment.

    Parameters
    ----------
    path : path-like
        PLY, STL or OBJ in millimetres, project frame.
    side : {'left', 'right'}
        Which ear the file holds; a right ear is mirrored (y -> -y) into a left one.
    margin_mm : float
        Width of the skin ring kept around the detected pinna (keep it under the template's 6 mm).
    segment : bool
        Cut the pinna out of a crop that holds head skin (False: use the whole mesh).
    scan_pose : {'project_frame', 'any'}
        'project_frame': the file is in mm in the head frame (checked, `side` says which ear); 'any': any
        orientation, offset, unit and side, found by :func:`ppm.align.any_pose.find_pose` (`side` ignored).

    Raises
    ------
    PpmError
        For unreadable, empty or NaN files, wrong units or side, or a mesh that holds no pinna;
        :class:`ppm.align.any_pose.PoseUncertainError` when the pose of an 'any' scan cannot be told.
    """
    pose = None
    if scan_pose == "any":
        mesh, pose = scan_in_project_frame(path)
    elif scan_pose == "project_frame":
        mesh = load_left_pinna(path, side)
    else:
        raise PpmError(f"scan_pose must be 'project_frame' or 'any', got {scan_pose!r}")
    mesh.remove_unreferenced_vertices()
    whole = mesh
    if segment:
        try:
            region = pinna_region(mesh, margin_mm=margin_mm)
        except PpmError as exc:
            raise PpmError(f"{path}: {exc}") from exc
        mesh = crop_to_region(mesh, region)
    target = dataclasses.replace(target_from_mesh(mesh, str(path)), scan=whole)
    if pose is None:
        return target
    from .any_pose import side_name  # noqa: PLC0415

    found = [f"pose found: {pose['unit']}, {side_name(pose['mirrored'])}, next other pose "
             f"{pose['runner_up_ratio']:g}x worse"]
    return dataclasses.replace(target, warnings=tuple(found) + target.warnings, pose=pose)


def scan_in_project_frame(path: str | os.PathLike) -> tuple[trimesh.Trimesh, dict]:
    """A scan in any pose, unit and side moved onto the packaged template (mm, project frame, left ear),
    and the pose's description (see :class:`ppm.align.any_pose.ScanPose`)."""
    from ..mesh_io import load_mesh  # noqa: PLC0415
    from ..template.store import load_template  # noqa: PLC0415
    from .any_pose import find_pose  # noqa: PLC0415
    from .pose import apply_similarity  # noqa: PLC0415

    mesh = load_mesh(path)
    template = load_template(None)
    pose = find_pose(mesh, trimesh.Trimesh(template.vertices_mm, template.faces, process=False), str(path))
    return apply_similarity(mesh, pose.matrix), {**pose.summary(), "matrix": pose.matrix.round(9).tolist()}


def target_from_mesh(mesh: trimesh.Trimesh, source: str) -> Target:
    """A target from a pinna surface (mm, project frame): outliers removed, holes measured.

    Raises
    ------
    PpmError
        If fewer than 500 usable points remain.
    """
    warnings: list[str] = []
    keep = remove_outliers(mesh.vertices)
    if (~keep).any():
        warnings.append(f"{int((~keep).sum())} isolated outlier points removed")
    share = hole_share(mesh)
    if share > MAX_HOLE_SHARE:
        warnings.append(f"about {100 * share:.0f} % of the pinna surface is missing to holes; "
                        "distances there are not measured and the fit is less constrained")
    normals = np.asarray(mesh.vertex_normals)
    points = np.asarray(mesh.vertices)[keep]
    if len(points) < 500:
        raise PpmError(f"{source}: only {len(points)} usable pinna points; a scan of about 1 mm resolution is needed")
    for message in warnings:
        log.warning("%s: %s", source, message)
    return Target(points, normals[keep], mesh, source, tuple(warnings))


def write_target(target: Target, mesh_path: str | os.PathLike, report_path: str | os.PathLike,
                 scan_path: str | os.PathLike | None = None) -> dict:
    """Write the prepared pinna surface (mm, left ear, project frame; outliers still in the mesh, they are
    found again when it is read), a JSON report of the preparation and, to ``scan_path``, the whole scan it was cut
    from in the same frame (:attr:`Target.scan`; the pinna surface where none is kept). All atomically."""
    import json  # noqa: PLC0415

    from core.atomic import write_text_atomic  # noqa: PLC0415
    from ..mesh_io import write_mesh  # noqa: PLC0415

    report = {"source": target.source, "n_points": int(len(target.points_mm)),
              "n_mesh_vertices": int(len(target.mesh.vertices)), "hole_share": round(hole_share(target.mesh), 4),
              "extent_mm": np.ptp(target.points_mm, axis=0).round(2).tolist(), "warnings": list(target.warnings)}
    if target.pose is not None:
        report["pose"] = target.pose
    write_mesh(mesh_path, target.mesh.vertices, target.mesh.faces)
    if scan_path is not None:
        whole = target.scan if target.scan is not None else target.mesh
        write_mesh(scan_path, whole.vertices, whole.faces)
    write_text_atomic(report_path, json.dumps(report, indent=2) + "\n")
    return report


def with_scan(target: Target, scan_path: str | os.PathLike) -> Target:
    """``target`` with :attr:`Target.scan` read from ``scan_path`` (written by :func:`write_target`: mm, project
    frame, left ear already, so nothing is mirrored or moved)."""
    return dataclasses.replace(target, scan=load_left_pinna(scan_path, "left"))
