"""Graded isotropic remeshing for BEM (millimetres): ~1 mm edges on the pinna and a margin around it,
coarser with distance, in the spirit of Mesh2HRTF's distance-based grading.

pymeshlab's isotropic explicit remeshing is applied band by band (finest first) to the faces whose
centroids lie in each distance band from the pinna, with the allowed surface deviation set
explicitly (never pymeshlab's size-relative default). A band whose edges already have the target
length (within ±25 %) is left as it is, so an already graded head keeps those parts.
"""
from __future__ import annotations

import dataclasses
import logging

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from core.self_intersections import self_intersecting_faces
from mesh2hrtf_io.checks import min_angles_deg

from .errors import StitchError

log = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class Band:
    """Faces whose distance (mm) to the pinna is below ``up_to_mm`` get edges of ``edge_mm``."""

    up_to_mm: float
    edge_mm: float
    max_deviation_mm: float


DEFAULT_BANDS = (Band(12.0, 1.0, 0.05), Band(30.0, 2.0, 0.1), Band(60.0, 3.5, 0.3), Band(np.inf, 6.0, 0.5))


def bands_from_config(bands: list[dict]) -> tuple[Band, ...]:
    """Bands from config entries {up_to_mm (None: the rest of the head), edge_mm, max_deviation_mm}."""
    return tuple(Band(float("inf") if b["up_to_mm"] is None else float(b["up_to_mm"]), float(b["edge_mm"]),
                      float(b["max_deviation_mm"])) for b in bands)


def _pymeshlab():
    import pymeshlab  # noqa: PLC0415  (imported late: after bpy where both are used)

    return pymeshlab


def _meshset_selecting(mesh: trimesh.Trimesh, selected: np.ndarray):
    """A pymeshlab MeshSet holding ``mesh`` with the faces of the boolean mask ``selected`` selected."""
    pymeshlab = _pymeshlab()
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(mesh.vertices, np.float64),
                               face_matrix=np.asarray(mesh.faces, np.int32),
                               f_scalar_array=np.asarray(selected, dtype=np.float64)))
    ms.compute_selection_by_condition_per_face(condselect="fq > 0.5")
    return ms


def _current_trimesh(ms) -> trimesh.Trimesh:
    out = ms.current_mesh()
    return trimesh.Trimesh(out.vertex_matrix(), out.face_matrix(), process=False)


def face_distance_to(points_mm: np.ndarray, mesh: trimesh.Trimesh) -> np.ndarray:
    """Distance (mm) of every face centroid to the nearest of ``points_mm``."""
    return cKDTree(points_mm).query(mesh.triangles_center)[0]


def remesh_graded(mesh: trimesh.Trimesh, pinna_points_mm: np.ndarray, bands=DEFAULT_BANDS,
                  iterations: int = 8, keep_centre_mm: np.ndarray | None = None,
                  keep_radius_mm: float = 0.0, coarsen_only: bool = False) -> trimesh.Trimesh:
    """Remesh ``mesh`` band by band around the pinna (points in mm); returns a new closed mesh. Faces whose
    centroids lie within ``keep_radius_mm`` of ``keep_centre_mm`` (one point or several, e.g. the ear-canal sources)
    are kept as they are. With ``coarsen_only`` a band whose edges are already longer than its target (less than
    25 % shorter) is kept: the mesh gets nowhere finer (a band mesh for low frequencies)."""
    pymeshlab = _pymeshlab()
    current = mesh
    lower = 0.0
    for band in bands:
        distance = face_distance_to(pinna_points_mm, current)
        selected = (distance >= lower) & (distance < band.up_to_mm)
        if keep_centre_mm is not None:
            centres = np.atleast_2d(keep_centre_mm)
            selected &= cKDTree(centres).query(current.triangles_center)[0] >= keep_radius_mm
        lower = band.up_to_mm
        if not selected.any():
            continue
        face_edges = current.faces_unique_edges[selected].ravel()
        median_edge = float(np.median(current.edges_unique_length[np.unique(face_edges)]))
        if abs(median_edge / band.edge_mm - 1) <= 0.25 or (coarsen_only and median_edge >= 0.75 * band.edge_mm):
            log.info("band < %.0f mm: median edge %.2f mm already near %.1f mm; kept", band.up_to_mm, median_edge,
                     band.edge_mm)
            continue
        ms = _meshset_selecting(current, selected)
        ms.meshing_isotropic_explicit_remeshing(iterations=iterations, selectedonly=True,
                                                targetlen=pymeshlab.PureValue(band.edge_mm), featuredeg=60.0,
                                                checksurfdist=True, maxsurfdist=pymeshlab.PureValue(band.max_deviation_mm))
        current = _current_trimesh(ms)
        log.info("band < %.0f mm: %d faces at median edge %.2f mm remeshed to %.1f mm; now %d faces", band.up_to_mm,
                 int(selected.sum()), median_edge, band.edge_mm, len(current.faces))
    if not (current.is_watertight and current.is_winding_consistent):
        raise StitchError("remeshing broke the surface (open or inconsistently wound); try fewer iterations or a "
                          "larger max deviation")
    return current


def self_intersections(mesh: trimesh.Trimesh) -> int:
    """Number of faces that intersect another face (MeshLab's test, core.self_intersections)."""
    return len(self_intersecting_faces(mesh.vertices, mesh.faces))


def repair_self_intersections(mesh: trimesh.Trimesh, rounds: int = 4) -> trimesh.Trimesh:
    """Relax the neighbourhood of self-intersecting faces (Laplacian steps on them and two rings around)
    until none is left or ``rounds`` are used; returns the mesh (unchanged if it had none)."""
    pymeshlab = _pymeshlab()
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(mesh.vertices, np.float64),
                               face_matrix=np.asarray(mesh.faces, np.int32)))
    for attempt in range(rounds):
        ms.compute_selection_by_self_intersections_per_face()
        count = ms.current_mesh().selected_face_number()
        if count == 0:
            break
        log.info("relaxing %d self-intersecting faces (round %d)", count, attempt + 1)
        for _ in range(2 + attempt):
            ms.apply_selection_dilatation()
        ms.apply_coord_laplacian_smoothing(stepsmoothnum=3, selected=True, cotangentweight=False)
    out = ms.current_mesh()
    return trimesh.Trimesh(out.vertex_matrix(), out.face_matrix(), process=False)


FOLD_DIHEDRAL_DEG = 120.0
"""Neighbouring triangles whose normals differ by more than this (degrees) fold over each other: a crumple in the
mesh, not anatomy. Of the nine heads of the SONICOM evaluation (three dataset heads, six built ones) only P067's
dataset head has such pairs (ten, at one spot below the concha, six above 150 deg); no other has a pair above
100 deg, its sharpest folds of the helix and the antihelix included."""


def folded_faces(mesh: trimesh.Trimesh, above_deg: float = FOLD_DIHEDRAL_DEG) -> np.ndarray:
    """Boolean mask of the faces that meet a neighbour at a dihedral angle (between normals) above ``above_deg``."""
    angles = np.degrees(mesh.face_adjacency_angles)
    folded = np.zeros(len(mesh.faces), dtype=bool)
    folded[mesh.face_adjacency[angles > above_deg].ravel()] = True
    return folded


def fill_folds(mesh: trimesh.Trimesh, above_deg: float = FOLD_DIHEDRAL_DEG, rounds: int = 2) -> trimesh.Trimesh:
    """Cut every fold (:func:`folded_faces`) out with two rings of faces around it and close each hole with a
    fill refined to the cut faces' size. Smoothing does not undo such a crumple (its triangles stay folded
    whatever the vertex positions: on P067's head, Laplacian steps left 4-8 folded faces), a new patch does; the
    surface there moves by up to the crumple's own depth (P067: 2 mm, over a patch 3 mm across). Returns the
    mesh (unchanged if it had none)."""
    pymeshlab = _pymeshlab()
    current = mesh
    for attempt in range(rounds):
        folded = folded_faces(current, above_deg)
        if not folded.any():
            break
        ms = _meshset_selecting(current, folded)
        ms.apply_selection_dilatation()
        ms.apply_selection_dilatation()
        cut = ms.current_mesh().face_selection_array()
        size = float(np.median(_face_sizes(current)[cut]))
        log.info("filling %d folded faces (dihedral > %.0f deg) with %d around them (round %d)", int(folded.sum()),
                 above_deg, int(cut.sum() - folded.sum()), attempt + 1)
        ms.meshing_remove_selected_faces()
        ms.meshing_remove_unreferenced_vertices()
        ms.meshing_close_holes(maxholesize=int(4 * cut.sum()) + 30, refinehole=True,
                               refineholeedgelen=pymeshlab.PureValue(size))
        current = _current_trimesh(ms)
    return current


SLIVER_REPAIR_BELOW_DEG = 10.0  # triangles with a smaller angle are remeshed with their neighbourhood
COARSE_NEIGHBOUR_FACTOR = 3.0  # in the first pass, neighbours this much larger than the slivers' own size stay


def _face_sizes(mesh: trimesh.Trimesh) -> np.ndarray:
    """Size (mm) of every triangle: the mean of its two longer edges (a needle's short edge left out)."""
    edges = np.sort(mesh.edges_unique_length[mesh.faces_unique_edges], axis=1)
    return edges[:, 1:].mean(axis=1)


def _sliver_pass(mesh: trimesh.Trimesh, below_deg: float, max_deviation_mm: float,
                 coarse_factor: float | None) -> trimesh.Trimesh:
    """One remeshing of the two rings around the triangles with an angle under ``below_deg``, at the median size
    of their neighbours; with ``coarse_factor``, neighbours larger than that many times it are left out (where a
    sliver sits at the border of a coarser band, the coarse faces are not refined)."""
    pymeshlab = _pymeshlab()
    bad = min_angles_deg(mesh.vertices, mesh.faces) < below_deg
    ms = _meshset_selecting(mesh, bad)
    ms.apply_selection_dilatation()
    ms.apply_selection_dilatation()
    selected = ms.current_mesh().face_selection_array()
    size = _face_sizes(mesh)
    target = float(np.median(size[selected & ~bad] if (selected & ~bad).any() else size[selected]))
    if coarse_factor is not None:
        selected = selected & ((size <= coarse_factor * target) | bad)
        ms = _meshset_selecting(mesh, selected)
    log.info("remeshing %d sliver triangles (angle < %.0f deg) with %d around them at %.2f mm", int(bad.sum()),
             below_deg, int(selected.sum()), target)
    ms.meshing_isotropic_explicit_remeshing(iterations=4, selectedonly=True, targetlen=pymeshlab.PureValue(target),
                                            featuredeg=120.0, checksurfdist=True,
                                            maxsurfdist=pymeshlab.PureValue(max_deviation_mm))
    return _current_trimesh(ms)


def remove_slivers(mesh: trimesh.Trimesh, below_deg: float = SLIVER_REPAIR_BELOW_DEG, rounds: int = 3,
                   max_deviation_mm: float = 0.05) -> trimesh.Trimesh:
    """Remesh the neighbourhood of every triangle with an angle under ``below_deg`` (needles and caps, e.g. at
    the border between a remeshed and a kept band) at its neighbours' size, with feature preservation relaxed to
    120 degrees there so that the short edge can collapse and the long one flip; every pass keeps its vertices
    within ``max_deviation_mm`` of the surface it starts from. The first two passes keep much coarser neighbours as
    they are (P039's stitched head: 30,642 faces -> 31,132, against 33,180 when they are refined too); passes that
    refine them follow for whatever is left, up to ``rounds``. Returns the mesh (unchanged if it had none)."""
    current = mesh
    for attempt in range(rounds + 1):
        if not (min_angles_deg(current.vertices, current.faces) < below_deg).any():
            break
        current = _sliver_pass(current, below_deg, max_deviation_mm,
                               COARSE_NEIGHBOUR_FACTOR if attempt < 2 else None)
    return current


REPAIR_ROUNDS = 3
"""Rounds of fold fill, sliver repair and self-intersection relaxing: the sliver repair can crease a patch again
(P143's ppm_detail_hard head: one pair of faces at 120.1 deg after the first round)."""


def repair_folds_and_slivers(mesh: trimesh.Trimesh, rounds: int = REPAIR_ROUNDS, sliver_rounds: int = 3,
                             max_deviation_mm: float = 0.05) -> trimesh.Trimesh:
    """Folds cut out and filled, slivers remeshed (``sliver_rounds`` passes, each within ``max_deviation_mm`` of
    its surface), self-intersections relaxed; again while a fold is left, up to ``rounds`` times. A mesh clean
    after the first round is what that round made."""
    for attempt in range(rounds):
        mesh = repair_self_intersections(remove_slivers(fill_folds(mesh), rounds=sliver_rounds,
                                                        max_deviation_mm=max_deviation_mm))
        if not folded_faces(mesh).any():
            break
        log.info("a fold is left after repair round %d; repairing again", attempt + 1)
    return mesh
