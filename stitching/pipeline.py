"""The stitch and remesh stages as file-to-file functions (millimetres, project frame), used by the
workflow rules and the ``stitch`` command. Outputs are written atomically, the mesh before its report."""
from __future__ import annotations

import json
import logging
import os
import time
from pathlib import Path

import numpy as np
import trimesh

from mesh2hrtf_io.checks import SLIVER_ANGLE_DEG
from core.atomic import write_text_atomic
from ppm.mesh_io import write_mesh

from mesh2hrtf_io.ear_canal import ear_canal_elements
from .both_ears import mirror_left_right, stitch_both_ears
from .errors import StitchError
from .remesh import DEFAULT_BANDS, fill_folds, remesh_graded, repair_folds_and_slivers, repair_self_intersections
from .replace_pinna import own_pinna_region, replace_pinna
from .report import validate_head
from .seam import smooth_seam

log = logging.getLogger(__name__)


def _load(path: str | os.PathLike, what: str) -> trimesh.Trimesh:
    path = Path(path)
    if not path.is_file() or path.stat().st_size == 0:
        raise StitchError(f"{path}: the {what} mesh is missing or empty")
    try:
        mesh = trimesh.load(path, process=False, force="mesh")
    except Exception as exc:  # trimesh raises many types for corrupt files
        raise StitchError(f"{path}: cannot be read as a {what} mesh ({exc})") from exc
    if len(mesh.faces) == 0:
        raise StitchError(f"{path}: the {what} mesh has no triangles")
    return mesh


def own_pinna_files(head_path: str | os.PathLike, pinna_path: str | os.PathLike, out_mesh: str | os.PathLike,
                    out_report: str | os.PathLike) -> dict:
    """The head's own left pinna under the aligned pinna, cut out as an open surface (mm) to be stitched back
    and remeshed like a PPM pinna: the own_pinna control of the evaluation."""
    start = time.perf_counter()
    head, pinna = _load(head_path, "head"), _load(pinna_path, "pinna")
    region = own_pinna_region(head, pinna, pinna_source=str(pinna_path))
    report = {"head": str(head_path), "pinna": str(pinna_path), "n_triangles": int(len(region.faces)),
              "area_mm2": round(float(region.area), 1), "seconds": round(time.perf_counter() - start, 2)}
    write_mesh(out_mesh, region.vertices, region.faces)
    write_text_atomic(out_report, json.dumps(report, indent=2) + "\n")
    return report


def scan_pinna_files(scan_path: str | os.PathLike, guide_path: str | os.PathLike, out_mesh: str | os.PathLike,
                     out_report: str | os.PathLike, out_surface: str | os.PathLike | None = None) -> dict:
    """The scan itself as the pinna (the scan_hard condition): a defective scan (mm, head frame) made watertight by
    outlier removal and screened Poisson reconstruction (:mod:`stitching.reconstruction`) and cut under the rim of
    ``guide_path`` (the PPM fitted to the same scan), as the head's own pinna is for own_pinna, so that both replace
    the same region of the head. The cut is made in the untrimmed reconstruction: under the rim its fill of the
    scan's holes is what makes the scan watertight (the trim would open the larger ones again). ``out_surface``
    keeps the trimmed reconstruction (faces within ``trim_mm`` of the scan), as a user would look at it."""
    from .reconstruction import poisson_surface, reconstruction_settings  # noqa: PLC0415

    start = time.perf_counter()
    scan, guide = _load(scan_path, "scan"), _load(guide_path, "guide pinna")
    reconstruction = poisson_surface(scan, source=str(scan_path))
    try:
        region = own_pinna_region(reconstruction.closed, guide, pinna_source=str(guide_path), tidy_boundary=True)
    except StitchError as error:
        raise StitchError(f"{scan_path}: its screened Poisson reconstruction cannot be cut to a pinna under the rim of "
                          f"{guide_path}: {error}") from error
    report = {"scan": str(scan_path), "guide_pinna": str(guide_path), **reconstruction.report(),
              "settings": reconstruction_settings(), "n_triangles": int(len(region.faces)),
              "area_mm2": round(float(region.area), 1), "seconds": round(time.perf_counter() - start, 2)}
    if out_surface is not None:
        write_mesh(out_surface, reconstruction.surface.vertices, reconstruction.surface.faces)
    write_mesh(out_mesh, region.vertices, region.faces)
    write_text_atomic(out_report, json.dumps(report, indent=2) + "\n")
    return report


def stitch_files(head_path: str | os.PathLike, pinna_path: str | os.PathLike, out_mesh: str | os.PathLike,
                 out_report: str | os.PathLike, gap_mm: float = 1.5,
                 right_pinna_path: str | os.PathLike | None = None) -> dict:
    """Replace the head's left pinna by the aligned PPM pinna and smooth the seam; with ``right_pinna_path`` (the
    right ear's fit, a left-ear shape as the PPM is) the right pinna too (:mod:`stitching.both_ears`)."""
    start = time.perf_counter()
    head, pinna = _load(head_path, "head"), _load(pinna_path, "pinna")
    if right_pinna_path is not None:
        right = _load(right_pinna_path, "right pinna")
        mesh = stitch_both_ears(head, pinna, right, gap_mm, str(head_path), str(pinna_path), str(right_pinna_path))
        report = {"head": str(head_path), "pinna": str(pinna_path), "right_pinna": str(right_pinna_path),
                  "n_triangles": int(len(mesh.faces)), "closed": bool(mesh.is_watertight),
                  "seconds": round(time.perf_counter() - start, 2)}
        write_mesh(out_mesh, mesh.vertices, mesh.faces)
        write_text_atomic(out_report, json.dumps(report, indent=2) + "\n")
        return report
    stitched = replace_pinna(head, pinna, gap_mm=gap_mm, head_source=str(head_path), pinna_source=str(pinna_path))
    mesh = smooth_seam(stitched.mesh, stitched.origin == 2)
    report = {"head": str(head_path), "pinna": str(pinna_path), "removed_head_faces": stitched.removed_head_faces,
              "seam_faces": int((stitched.origin == 2).sum()), "rim_gap_mm": stitched.rim_gap_mm,
              "n_triangles": int(len(mesh.faces)), "closed": bool(mesh.is_watertight),
              "seconds": round(time.perf_counter() - start, 2)}
    write_mesh(out_mesh, mesh.vertices, mesh.faces)
    write_text_atomic(out_report, json.dumps(report, indent=2) + "\n")
    return report


def remesh_files(stitched_path: str | os.PathLike, pinna_path: str | os.PathLike, out_mesh: str | os.PathLike,
                 out_report: str | os.PathLike, bands=DEFAULT_BANDS,
                 right_pinna_path: str | os.PathLike | None = None) -> dict:
    """Graded remeshing around the pinna (both pinnae with ``right_pinna_path``, the right ear's fit as a left-ear
    shape), self-intersection and sliver repair, and the validation report."""
    start = time.perf_counter()
    stitched, pinna = _load(stitched_path, "stitched head"), _load(pinna_path, "pinna")
    points = np.asarray(pinna.vertices)
    right = None if right_pinna_path is None else mirror_left_right(_load(right_pinna_path, "right pinna"))
    if right is not None:
        points = np.vstack([points, np.asarray(right.vertices)])
    # a crumple (folded triangles) is cut out before the remeshing and again after it (the remesher may fold a
    # patch it cannot smooth), then slivers go
    mesh = repair_self_intersections(remesh_graded(fill_folds(stitched), points, bands))
    mesh = repair_folds_and_slivers(mesh)
    report = validate_head(mesh, pinna)
    if right is not None:
        report["right_pinna_edge_mm"] = validate_head(mirror_left_right(mesh),
                                                      mirror_left_right(right))["pinna_edge_mm"]
    # the reciprocal sources for the exporter: ear-canal entrance faces of the final mesh
    report["ear_elements"] = {side: ear_canal_elements(mesh, side, source=str(out_mesh)).tolist()
                              for side in ("left", "right")}
    report.update(stitched=str(stitched_path), seconds=round(time.perf_counter() - start, 2),
                  bands=[{"up_to_mm": b.up_to_mm if np.isfinite(b.up_to_mm) else None, "edge_mm": b.edge_mm,
                          "max_deviation_mm": b.max_deviation_mm} for b in bands])
    if not report["ok"]:
        raise StitchError(f"{stitched_path}: the remeshed head is not fit for BEM: {report['problems']}, "
                          f"{report['self_intersecting_faces']} self-intersecting faces, {report['sliver_faces']} sliver "
                          f"triangles (an angle under {SLIVER_ANGLE_DEG:g} deg), {report['folded_faces']} folded faces")
    write_mesh(out_mesh, mesh.vertices, mesh.faces)
    write_text_atomic(out_report, json.dumps(report, indent=2) + "\n")
    log.info("remeshed %s: %d triangles, pinna edges median %.2f mm", out_mesh, report["n_triangles"],
             report["pinna_edge_mm"]["median"])
    return report
