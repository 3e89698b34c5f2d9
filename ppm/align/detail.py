"""The personal-detail layer: what a scan shows of an ear that the PPM's 144 parameters cannot take.

On top of a PPM fit, each vertex of the posed PPM moves along its own normal (same vertices, same faces) towards
the scan, by a smooth, bounded offset field that only trusted scan evidence drives: surface that is there, near,
facing the same way, away from the scan's open edges (the crop's edge, the rims of holes) and in agreement with
its neighbours (not a spike or an outlier sheet). Where the scan says nothing the offsets fall to zero and the
PPM's shape stays; the rim that the stitch joins to the head stays where the PPM put it; no face folds.

Millimetres, project frame (x front, y left, z up); the settings and their meaning are in
``ppm/data/personal_detail.yaml``.
"""
from __future__ import annotations

import dataclasses
from functools import lru_cache
from importlib import resources

import numpy as np
import scipy.sparse as sp
import trimesh
import yaml
from scipy.sparse.csgraph import dijkstra
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from ..errors import PpmError
from ..model import DETAIL_KEY  # noqa: F401  (the shape key that holds the layer in a .blend)
from .report import boundary_samples
from .target import Target, surface_without_outliers

@dataclasses.dataclass(frozen=True)
class DetailSettings:
    """The layer's settings (see ``ppm/data/personal_detail.yaml``; lengths in mm, angles in degrees)."""

    reach_mm: float
    normal_agreement_deg: float
    edge_margin_mm: float
    spike_mm: float
    spike_radius_mm: float
    smoothness_mm2: float
    decay: float
    rim_taper_mm: float
    max_offset_mm: float
    iterations: int

    @classmethod
    def packaged(cls, **overrides) -> "DetailSettings":
        """The packaged settings, with `overrides` (field=value) replaced."""
        values = {**_packaged_settings(), **overrides}
        unknown = set(values) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise PpmError(f"ppm/data/personal_detail.yaml: unknown setting(s) {sorted(unknown)}")
        return cls(**values)


@lru_cache(maxsize=1)
def _packaged_settings() -> dict:
    return yaml.safe_load(resources.files("ppm").joinpath("data/personal_detail.yaml").read_text(encoding="utf-8"))


@dataclasses.dataclass(frozen=True)
class PersonalDetail:
    """A personal-detail layer of one posed PPM.

    offsets_mm : (n,) offset of every vertex along ``normals`` (mm).
    normals : (n, 3) unit vertex normals of the posed PPM the offsets go along.
    trusted : (n,) whether the vertex took scan evidence in the last iteration.
    halvings : rounds of halving the offsets around folded faces.
    """

    offsets_mm: np.ndarray
    normals: np.ndarray
    trusted: np.ndarray
    halvings: int

    @property
    def displacement_mm(self) -> np.ndarray:
        """(n, 3) displacement of every vertex (mm)."""
        return self.offsets_mm[:, None] * self.normals

    def summary(self) -> dict:
        """Figures for a fit's report (mm and shares)."""
        size = np.abs(self.offsets_mm)
        return {"trusted_share": round(float(self.trusted.mean()), 4),
                "offset_median_mm": round(float(np.median(size)), 4),
                "offset_p95_mm": round(float(np.percentile(size, 95)), 4),
                "offset_max_mm": round(float(size.max()), 4), "fold_halvings": self.halvings}


def rim_vertices(faces: np.ndarray) -> np.ndarray:
    """Indices of the vertices on the mesh's open boundary (the pinna's skin-ring rim)."""
    edges = np.sort(np.asarray(faces)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    return np.unique(unique[counts == 1])


def _edges(faces: np.ndarray) -> np.ndarray:
    edges = np.sort(np.asarray(faces)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    return np.unique(edges, axis=0)


def laplacian(vertices_mm: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """Graph Laplacian with edge weights 1 / length^2 (1/mm^2), so that s^T L s approximates the integral of
    |grad s|^2 per unit area on an even mesh."""
    edges = _edges(faces)
    length = np.linalg.norm(vertices_mm[edges[:, 0]] - vertices_mm[edges[:, 1]], axis=1)
    weight = 1.0 / np.maximum(length, 1e-3) ** 2
    n = len(vertices_mm)
    adjacency = sp.coo_matrix((np.r_[weight, weight], (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                              shape=(n, n)).tocsr()
    return (sp.diags(np.asarray(adjacency.sum(axis=1)).ravel()) - adjacency).tocsr()


def rim_taper(vertices_mm: np.ndarray, faces: np.ndarray, taper_mm: float) -> np.ndarray:
    """(n,) factor 0 on the rim rising smoothly to 1 at ``taper_mm`` along the surface from it."""
    rim = rim_vertices(faces)
    if len(rim) == 0 or taper_mm <= 0:
        return np.ones(len(vertices_mm))
    edges = _edges(faces)
    length = np.linalg.norm(vertices_mm[edges[:, 0]] - vertices_mm[edges[:, 1]], axis=1)
    n = len(vertices_mm)
    graph = sp.coo_matrix((length, (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    distance = dijkstra(graph, directed=False, indices=rim, min_only=True, limit=taper_mm * 1.5)
    x = np.clip(distance / taper_mm, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _face_normals(vertices_mm: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = vertices_mm[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)


def scan_evidence(vertices_mm: np.ndarray, normals: np.ndarray, scan: trimesh.Trimesh, edge_tree: cKDTree | None,
                  settings: DetailSettings) -> tuple[np.ndarray, np.ndarray]:
    """(normal offset r from every vertex to its closest scan point along its normal, mm; trust mask)."""
    closest, distance, triangle = trimesh.proximity.closest_point(scan, vertices_mm)
    offset = np.einsum("ij,ij->i", closest - vertices_mm, normals)
    agree = np.einsum("ij,ij->i", scan.face_normals[triangle], normals) >= np.cos(np.deg2rad(settings.normal_agreement_deg))
    trusted = (distance <= settings.reach_mm) & agree
    if edge_tree is not None:
        trusted &= edge_tree.query(closest)[0] >= settings.edge_margin_mm
    if trusted.any():  # neighbours agree: a spike or an outlier sheet stands out of its neighbourhood
        kept = np.flatnonzero(trusted)
        tree = cKDTree(vertices_mm[kept])
        groups = tree.query_ball_point(vertices_mm[kept], settings.spike_radius_mm)
        local = np.array([np.median(offset[kept[g]]) for g in groups])
        trusted[kept[np.abs(offset[kept] - local) > settings.spike_mm]] = False
    return offset, trusted


def personal_detail(vertices_mm: np.ndarray, faces: np.ndarray, target: Target,
                    settings: DetailSettings | None = None) -> PersonalDetail:
    """The personal-detail layer of a posed PPM (``vertices_mm``, ``faces``: mm, project frame) on ``target``."""
    settings = settings or DetailSettings.packaged()
    vertices_mm = np.asarray(vertices_mm, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if not np.isfinite(vertices_mm).all():
        raise PpmError("the posed PPM has non-finite vertices; fit it again before adding the personal detail")
    normals = np.asarray(trimesh.Trimesh(vertices_mm, faces, process=False).vertex_normals, dtype=np.float64)
    scan = surface_without_outliers(target)
    edges = boundary_samples(scan)
    edge_tree = cKDTree(edges) if len(edges) else None
    n = len(vertices_mm)
    taper = rim_taper(vertices_mm, faces, settings.rim_taper_mm)
    free = np.flatnonzero(taper > 0.0)
    system = (settings.smoothness_mm2 * laplacian(vertices_mm, faces) + settings.decay * sp.identity(n)).tocsr()
    system = system[free][:, free]
    offsets = np.zeros(n)
    trusted = np.zeros(n, dtype=bool)
    for _ in range(max(1, settings.iterations)):
        residual, trusted = scan_evidence(vertices_mm + offsets[:, None] * normals, normals, scan, edge_tree, settings)
        wanted = offsets + residual
        weight = trusted[free].astype(np.float64)
        solved = spsolve((system + sp.diags(weight)).tocsc(), weight * wanted[free])
        offsets = np.zeros(n)
        offsets[free] = solved
        offsets *= taper
    offsets = np.clip(offsets, -settings.max_offset_mm, settings.max_offset_mm)
    reference = _face_normals(vertices_mm, faces)
    halvings = 0
    for halvings in range(0, 31):
        moved = vertices_mm + offsets[:, None] * normals
        folded = np.einsum("ij,ij->i", _face_normals(moved, faces), reference) <= 0.0
        if not folded.any():
            break
        offsets[np.unique(faces[folded])] *= 0.5
    else:
        raise PpmError("the personal-detail layer keeps folding faces after 30 halvings; check the fit")
    return PersonalDetail(offsets_mm=offsets, normals=normals, trusted=trusted, halvings=halvings)


def add_personal_detail(model, target: Target, settings: DetailSettings | None = None) -> tuple[PersonalDetail, dict]:
    """Add the personal-detail layer of ``model`` (a :class:`ppm.model.PinnaModel` posed by a fit) on ``target``
    as its shape key :data:`DETAIL_KEY` at weight 1; returns the layer and a summary (the scan -> pinna distances
    without and with it, mm; the layer's figures)."""
    from .report import distance_summary, one_sided_distances_mm  # noqa: PLC0415

    if model.detail_weight:
        model.set_detail_weight(0.0)
    posed = model.evaluate()
    detail = personal_detail(posed, model.faces, target, settings)
    mismatch = model.set_personal_detail(detail.displacement_mm, 1.0)
    with_detail = model.evaluate()
    summary = {"ppm": distance_summary(one_sided_distances_mm(target, posed, model.faces)),
               "ppm_detail": distance_summary(one_sided_distances_mm(target, with_detail, model.faces)),
               "layer": detail.summary(), "shape_key": DETAIL_KEY, "shape_key_mismatch_mm": round(mismatch, 6),
               "settings": dataclasses.asdict(settings or DetailSettings.packaged())}
    return detail, summary
