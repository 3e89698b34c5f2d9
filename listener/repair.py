"""A head scan made into one closed, outward BEM surface, or refused with the reason.

Scans are often open at the neck (where the scanner stopped) or have small holes; pymeshlab merges duplicate
vertices, removes degenerate and unreferenced pieces, keeps the largest connected part and closes holes up to
a neck's cut (500 mm around). What is still open or non-manifold after that cannot be repaired here.
"""
from __future__ import annotations

import numpy as np
import trimesh

from mesh2hrtf_io.checks import mesh_problems

from .errors import ListenerError

#: Largest hole closed (perimeter, mm): a neck cut is 300-400 mm around; a larger hole is missing head.
MAX_HOLE_PERIMETER_MM = 500.0


def closed_head(head: trimesh.Trimesh, source: str = "head mesh") -> tuple[trimesh.Trimesh, list[str]]:
    """``head`` (mm) as one closed surface with outward normals, and what was repaired (empty if nothing).

    Raises
    ------
    ListenerError
        If the surface cannot be closed: a hole larger around than a neck's cut (part of the head missing), or
        non-manifold edges that remain.
    """
    if not mesh_problems(head.vertices, head.faces):
        return head, []
    import pymeshlab  # noqa: PLC0415  (after bpy, where both are used in one process)

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(head.vertices, np.float64), np.asarray(head.faces, np.int32)))
    before = (ms.current_mesh().vertex_number(), ms.current_mesh().face_number())
    ms.meshing_merge_close_vertices(threshold=pymeshlab.PureValue(1e-6))
    ms.meshing_remove_duplicate_faces()
    ms.meshing_remove_null_faces()
    ms.meshing_remove_connected_component_by_diameter(mincomponentdiag=pymeshlab.PercentageValue(50.0))
    ms.meshing_repair_non_manifold_edges()
    ms.meshing_remove_unreferenced_vertices()
    cleaned = ms.current_mesh()
    check_holes(trimesh.Trimesh(cleaned.vertex_matrix(), cleaned.face_matrix(), process=False), source)
    ms.meshing_close_holes(maxholesize=len(head.faces), newfaceselected=False)
    ms.meshing_re_orient_faces_coherently()
    mesh = ms.current_mesh()
    repaired = trimesh.Trimesh(mesh.vertex_matrix(), mesh.face_matrix(), process=False)
    if repaired.is_watertight and repaired.volume < 0:
        repaired = trimesh.Trimesh(repaired.vertices, repaired.faces[:, ::-1].copy(), process=False)
    problems = mesh_problems(repaired.vertices, repaired.faces)
    if problems:
        raise ListenerError(f"{source}: the head scan cannot be made one closed surface:\n  - " + "\n  - ".join(problems)
                            + "\nclose it in the scanner's software or MeshLab (holes larger than a neck's cut are "
                            "not filled here)")
    notes = [f"repaired: {before[0]} -> {len(repaired.vertices)} vertices, {before[1]} -> {len(repaired.faces)} "
             "faces (merged, cleaned, holes closed)"]
    return repaired, notes


def check_holes(mesh: trimesh.Trimesh, source: str = "head mesh") -> None:
    """Refuse a scan (mm, vertices merged) with a hole larger around than a neck's cut (``MAX_HOLE_PERIMETER_MM``)."""
    boundary = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)
    if len(boundary) == 0:
        return
    edges = mesh.edges_sorted[boundary]
    graph = trimesh.graph.connected_components(edges, min_len=2)
    for loop in graph:
        inside = np.isin(edges, loop).all(axis=1)
        perimeter = float(np.linalg.norm(np.diff(mesh.vertices[edges[inside]], axis=1)[:, 0], axis=1).sum())
        if perimeter > MAX_HOLE_PERIMETER_MM:
            raise ListenerError(f"{source}: the scan has a hole {perimeter:.0f} mm around (a neck's cut is under "
                                f"{MAX_HOLE_PERIMETER_MM:g} mm): part of the head is missing; scan the whole head")
