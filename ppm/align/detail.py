"""The personal-detail layer: what a scan shows of an ear that the PPM's 144 parameters cannot take.

On top of a PPM fit, every vertex of the posed PPM moves (same vertices, same faces) towards the scan, by a smooth,
bounded displacement field that only trusted scan evidence drives: surface that is there, near, facing the same
way, over the scan rather than beyond its open edges (the crop's edge, the rims of holes) and in agreement with its
neighbours (not a spike or an outlier sheet). Where the scan says nothing the field stays smooth and fades, so the
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
from scipy.spatial import cKDTree

from core.self_intersections import self_intersecting_faces

from ..errors import PpmError
from ..geodesic import rim_vertices  # noqa: F401  (the layer holds the rim; tests import it from here)
from ..model import DETAIL_KEY  # the shape key that holds the layer in a .blend
from .report import boundary_samples
from .scan_noise import scan_noise_mm, settle_strays, stray_points
from .target import Target, surface_without_outliers


@dataclasses.dataclass(frozen=True)
class DetailSettings:
    """The layer's settings (see ``ppm/data/personal_detail.yaml``; lengths in mm, angles in degrees)."""

    reach_mm: float
    normal_agreement_deg: float
    edge_margin_mm: float
    over_surface_deg: float
    spike_mm: float
    spike_radius_mm: float
    stiffness_mm2: tuple[float, ...]
    iterations_per_stiffness: int
    decay: float
    reverse_weight: float
    rim_taper_mm: float
    max_displacement_mm: float
    crease_limit_deg: float
    facing_pairs: bool = False
    roughness_limit_deg: float | None = None
    evidence_fade_mm: float | None = None
    fold_smoothing_rounds: int = 0
    hole_fill_mm: float | None = None
    noise_stiffness_factor: float | None = None
    forward_weight: float = 1.0
    outlier_sigmas: float | None = None
    outlier_floor_mm: float = 0.3

    @classmethod
    def packaged(cls, **overrides) -> "DetailSettings":
        """The packaged settings, with `overrides` (field=value) replaced."""
        values = {**_packaged_settings(), **overrides}
        unknown = set(values) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise PpmError(f"ppm/data/personal_detail.yaml: unknown setting(s) {sorted(unknown)}")
        values["stiffness_mm2"] = tuple(float(v) for v in values["stiffness_mm2"])
        return cls(**values)


@lru_cache(maxsize=1)
def _packaged_settings() -> dict:
    return yaml.safe_load(resources.files("ppm").joinpath("data/personal_detail.yaml").read_text(encoding="utf-8"))


@dataclasses.dataclass(frozen=True)
class PersonalDetail:
    """A personal-detail layer of one posed PPM.

    displacement_mm : (n, 3) displacement of every vertex (mm, project frame).
    trusted : (n,) whether the vertex took scan evidence in the last iteration.
    halvings : rounds of halving the displacements around folded faces.
    smoothings : rounds of smoothing the field around folded faces (before any halving).
    stages : stiffness stages of the schedule kept (fewer than the schedule's where the roughness guard stopped it).
    noise_mm : the scan's noise (:func:`ppm.align.scan_noise.scan_noise_mm`, mm) where ``noise_stiffness_factor``
        asked for it, else None.
    stiffness_mm2 : the schedule laid (mm²): the packaged one, ended at the noise's floor where there is one.
    strays : scan vertices settled onto their neighbours' surface as standing off it (``outlier_sigmas``; None: not
        asked).
    """

    displacement_mm: np.ndarray
    trusted: np.ndarray
    halvings: int
    stages: int = 0
    smoothings: int = 0
    noise_mm: float | None = None
    stiffness_mm2: tuple[float, ...] = ()
    strays: int | None = None

    @property
    def size_mm(self) -> np.ndarray:
        """(n,) length of every vertex's displacement (mm)."""
        return np.linalg.norm(self.displacement_mm, axis=1)

    def summary(self) -> dict:
        """Figures for a fit's report (mm and shares)."""
        size = self.size_mm
        strays = {} if self.strays is None else {"stray_scan_points": self.strays}
        return {"trusted_share": round(float(self.trusted.mean()), 4),
                "displacement_median_mm": round(float(np.median(size)), 4),
                "displacement_p95_mm": round(float(np.percentile(size, 95)), 4),
                "displacement_max_mm": round(float(size.max()), 4), "fold_halvings": self.halvings,
                "fold_smoothings": self.smoothings, "stiffness_stages": self.stages,
                "scan_noise_mm": None if self.noise_mm is None else round(self.noise_mm, 4),
                "stiffness_end_mm2": self.stiffness_mm2[-1] if self.stiffness_mm2 else None, **strays}


def joined_evidence(scan: Target, fill: trimesh.Trimesh) -> Target:
    """The layer's evidence: the prepared scan's surface joined with ``fill`` (a surface where the scan has none,
    e.g. a reconstruction's fill of its holes: ``stitching.reconstruction.layer_evidence``), mm, project frame. The
    two keep their own faces and open edges; the fill's outward normals must agree with the scan's."""
    if len(fill.faces) == 0:
        return scan
    joined = trimesh.util.concatenate([trimesh.Trimesh(scan.mesh.vertices, scan.mesh.faces, process=False),
                                       trimesh.Trimesh(fill.vertices, fill.faces, process=False)])
    return Target(np.asarray(joined.vertices), np.asarray(joined.vertex_normals), joined,
                  f"{scan.source} with its reconstruction's fill of {len(fill.faces)} faces", scan.warnings, scan.pose)


def _edges(faces: np.ndarray) -> np.ndarray:
    edges = np.sort(np.asarray(faces)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    return np.unique(edges, axis=0)


def _adjacency(edges: np.ndarray, weight: np.ndarray, n: int) -> sp.csr_matrix:
    """(n, n) symmetric matrix with ``weight`` on each of the (unique) ``edges``, both ways."""
    return sp.coo_matrix((np.r_[weight, weight], (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                         shape=(n, n)).tocsr()


def laplacian(vertices_mm: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """Graph Laplacian with edge weights 1 / length^2 (1/mm^2), so that s^T L s approximates the integral of
    |grad s|^2 per unit area on an even mesh."""
    edges = _edges(faces)
    length = np.linalg.norm(vertices_mm[edges[:, 0]] - vertices_mm[edges[:, 1]], axis=1)
    adjacency = _adjacency(edges, 1.0 / np.maximum(length, 1e-3) ** 2, len(vertices_mm))
    return (sp.diags(np.asarray(adjacency.sum(axis=1)).ravel()) - adjacency).tocsr()


def neighbour_mean(faces: np.ndarray, n: int) -> sp.csr_matrix:
    """(n, n) operator that gives each vertex the mean of its mesh neighbours' values (a vertex without neighbours
    keeps 0)."""
    edges = _edges(faces)
    adjacency = _adjacency(edges, np.ones(len(edges)), n)
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return (sp.diags(1.0 / np.maximum(degree, 1.0)) @ adjacency).tocsr()


def smooth_around(displacement_mm: np.ndarray, folded_vertices: np.ndarray, mean: sp.csr_matrix,
                  held: np.ndarray) -> None:
    """One round of untangling in place: the vertices of folded faces and their neighbours (not the ``held`` ones,
    the rim) take the mean of their neighbours' displacements (mm), so that a fold is ironed out by its surroundings'
    displacement instead of pulled back to the PPM (which halving does)."""
    around = np.zeros(len(displacement_mm), dtype=bool)
    around[folded_vertices] = True
    around |= (mean @ around.astype(np.float64)) > 0.0
    around &= ~held
    displacement_mm[around] = (mean @ displacement_mm)[around]


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


def closest_within(mesh: trimesh.Trimesh, points_mm: np.ndarray, reach_mm: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest points on ``mesh`` of the ``points_mm`` that may lie within ``reach_mm`` of it (closest point,
    distance, triangle); the others keep their own position, an infinite distance and triangle 0. A point farther
    than ``reach_mm`` plus the longest edge from every vertex lies beyond ``reach_mm`` of the surface, and trimesh's
    exact query is slow for far points, so they are left out of it."""
    points_mm = np.asarray(points_mm, dtype=np.float64)
    closest, distance = points_mm.copy(), np.full(len(points_mm), np.inf)
    triangle = np.zeros(len(points_mm), dtype=np.int64)
    longest = float(mesh.edges_unique_length.max()) if len(mesh.faces) else 0.0
    near = np.isfinite(cKDTree(mesh.vertices).query(points_mm, distance_upper_bound=reach_mm + longest)[0])
    if near.any():
        closest[near], distance[near], triangle[near] = trimesh.proximity.closest_point(mesh, points_mm[near])
    return closest, distance, triangle


#: Faces (nearest by centroid) among which :func:`closest_facing` looks for a point on a face turned the same way.
FACING_CANDIDATES = 24


def closest_facing(mesh: trimesh.Trimesh, points_mm: np.ndarray, normals: np.ndarray, reach_mm: float,
                   agreement_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Like :func:`closest_within`, but each point's closest point on the faces of ``mesh`` whose normals lie within
    ``agreement_deg`` of the point's own normal (of the :data:`FACING_CANDIDATES` faces nearest by centroid): on a
    sheet thinner than the pairs' offsets (a lobule, a helix rim) the nearest point can lie on the far face, turned
    away, where this finds the near one. Points with no such face keep their own position and an infinite distance."""
    points_mm = np.asarray(points_mm, dtype=np.float64)
    closest, distance = points_mm.copy(), np.full(len(points_mm), np.inf)
    triangle = np.zeros(len(points_mm), dtype=np.int64)
    if len(mesh.faces) == 0 or len(points_mm) == 0:
        return closest, distance, triangle
    longest = float(mesh.edges_unique_length.max())
    count = min(FACING_CANDIDATES, len(mesh.faces))
    gap, candidate = cKDTree(mesh.triangles_center).query(points_mm, k=count, distance_upper_bound=reach_mm + longest)
    gap, candidate = gap.reshape(len(points_mm), count), candidate.reshape(len(points_mm), count)
    valid = np.isfinite(gap)
    candidate[~valid] = 0
    facing = valid & (np.einsum("ikj,ij->ik", mesh.face_normals[candidate], normals)
                      >= np.cos(np.deg2rad(agreement_deg)))
    rows, columns = np.nonzero(facing)
    if len(rows) == 0:
        return closest, distance, triangle
    faces = candidate[rows, columns]
    on_face = trimesh.triangles.closest_point(mesh.triangles[faces], points_mm[rows])
    length = np.linalg.norm(on_face - points_mm[rows], axis=1)
    order = np.lexsort((length, rows))
    best = order[np.unique(rows[order], return_index=True)[1]]
    closest[rows[best]], distance[rows[best]], triangle[rows[best]] = on_face[best], length[best], faces[best]
    return closest, distance, triangle


def surface_roughness_deg(vertices_mm: np.ndarray, faces: np.ndarray) -> float:
    """The 99th percentile of the angles (deg) between the normals of neighbouring faces: on the PPM's 1 mm mesh
    36-38 deg on the SONICOM fits; a layer that follows a noisy scan's 0.5 mm noise raises it to 57-63 deg."""
    mesh = trimesh.Trimesh(vertices_mm, faces, process=False)
    return float(np.percentile(np.degrees(mesh.face_adjacency_angles), 99))


def neighbours_agree(points_mm: np.ndarray, offsets_mm: np.ndarray, radius_mm: float, tolerance_mm: float) -> np.ndarray:
    """Whether each point's offset lies within ``tolerance_mm`` of the median offset of the points within
    ``radius_mm`` of it (a spike or an outlier sheet stands out of its neighbourhood)."""
    if len(points_mm) == 0:
        return np.zeros(0, dtype=bool)
    groups = cKDTree(points_mm).query_ball_point(points_mm, radius_mm)
    local = np.array([np.median(offsets_mm[group]) for group in groups])
    return np.abs(offsets_mm - local) <= tolerance_mm


def _trusted_pairs(points_mm: np.ndarray, normals: np.ndarray, closest: np.ndarray, distance: np.ndarray,
                   closest_normals: np.ndarray, scan_edge: cKDTree | None, edge_points: np.ndarray,
                   ppm_points: np.ndarray, settings: DetailSettings) -> np.ndarray:
    """Which correspondences (points -> their closest points on the other surface) are trusted: near, facing the
    same way, over the scan's surface rather than beyond its open edge, and in agreement with their neighbours.
    ``edge_points``: where each pair touches the scan (the closest point for model -> scan, the point itself for
    scan -> model); ``ppm_points``: where it touches the PPM, whose neighbourhood judges it (a spike's tip stands
    alone in space, but over a PPM surface where every other pair says otherwise)."""
    trusted = (distance <= settings.reach_mm) & (
        np.einsum("ij,ij->i", closest_normals, normals) >= np.cos(np.deg2rad(settings.normal_agreement_deg)))
    if scan_edge is not None:
        # near the scan's open boundary (the crop's edge, a hole's rim) a pair counts only where it runs along the
        # normal: a point over the surface, not one beyond the edge that the edge merely happens to be closest to
        near_edge = scan_edge.query(edge_points)[0] < settings.edge_margin_mm
        along = np.abs(np.einsum("ij,ij->i", closest - points_mm, closest_normals))
        over = (along >= np.cos(np.deg2rad(settings.over_surface_deg)) * distance) | (distance < 0.1)
        trusted &= ~(near_edge & ~over)
    kept = np.flatnonzero(trusted)
    offsets = np.einsum("ij,ij->i", closest[kept] - points_mm[kept], closest_normals[kept])
    trusted[kept[~neighbours_agree(ppm_points[kept], offsets, settings.spike_radius_mm, settings.spike_mm)]] = False
    return trusted


def noise_schedule(stiffness_mm2: tuple[float, ...], noise_mm: float, factor: float) -> tuple[float, ...]:
    """The stiffness schedule (mm², stiff to supple) ended at ``factor`` x ``noise_mm``² where that lies above its
    last stage: the stages stiffer than that floor, then the floor itself. A field more supple than the scan's noise
    allows follows the noise (the `hard` level's 0.5 mm at 0.1 mm²); on a clean scan the floor lies below the
    schedule's end and the schedule stays."""
    floor = factor * noise_mm * noise_mm
    if floor <= stiffness_mm2[-1]:
        return tuple(stiffness_mm2)
    return tuple(s for s in stiffness_mm2 if s > floor) + (round(floor, 4),)


def evidence_fade(vertices_mm: np.ndarray, evidence: np.ndarray, fade_mm: float) -> np.ndarray:
    """Per vertex, 1 within ``fade_mm`` (straight line, mm) of a vertex with evidence (``evidence``: bool per vertex),
    falling linearly to 0 at twice that: the field kept near what the scan shows, the PPM's shape where it shows
    nothing. All 0 when no vertex has evidence."""
    if not evidence.any():
        return np.zeros(len(vertices_mm))
    distance = cKDTree(vertices_mm[evidence]).query(vertices_mm)[0]
    return np.clip(2.0 - distance / fade_mm, 0.0, 1.0)


def unfold(vertices_mm: np.ndarray, faces: np.ndarray, displacement_mm: np.ndarray, held: np.ndarray,
           settings: DetailSettings) -> tuple[np.ndarray, int, int]:
    """The field (mm) with no face folded: none turned against the PPM's, no neighbours creased beyond
    ``crease_limit_deg`` and the PPM's own crease there. First up to ``fold_smoothing_rounds`` rounds of
    :func:`smooth_around` (``held``: vertices that stay, the rim), then halving the displacements around every folded
    face until none is; returns the field, the halvings and the smoothing rounds."""
    displacement = np.array(displacement_mm, dtype=np.float64)
    n = len(vertices_mm)
    reference = _face_normals(vertices_mm, faces)
    pairs = trimesh.Trimesh(vertices_mm, faces, process=False).face_adjacency
    crease_cos = np.minimum(np.cos(np.deg2rad(settings.crease_limit_deg)),
                            np.einsum("ij,ij->i", reference[pairs[:, 0]], reference[pairs[:, 1]])) - 1e-9
    mean = neighbour_mean(faces, n) if settings.fold_smoothing_rounds > 0 else None
    smoothings = halvings = 0
    while True:
        normals = _face_normals(vertices_mm + displacement, faces)
        folded = np.einsum("ij,ij->i", normals, reference) <= 0.0
        creased = np.einsum("ij,ij->i", normals[pairs[:, 0]], normals[pairs[:, 1]]) < crease_cos
        folded[pairs[creased].ravel()] = True
        if not folded.any():
            return displacement, halvings, smoothings
        if smoothings < settings.fold_smoothing_rounds:
            smooth_around(displacement, np.unique(faces[folded]), mean, held)
            smoothings += 1
            continue
        if halvings == 60:
            raise PpmError("the personal-detail layer keeps folding faces after 60 halvings; check the fit")
        displacement[np.unique(faces[folded])] *= 0.5
        halvings += 1


def evidence_surface(target: Target, settings: DetailSettings) -> tuple[trimesh.Trimesh, np.ndarray | None]:
    """The surface the layer pairs with (mm, project frame): ``target``'s without its isolated outliers, and with
    ``outlier_sigmas`` its stray points settled onto their neighbours' surface; and which of its vertices were strays
    (None where the test is off). Strays are outliers near the surface, which the isolation test keeps: their faces
    form tents that pairs agree on; settled, the scan keeps its faces. The test takes the scan's own noise
    (``target.noise_mm``, as ``stitching.reconstruction.layer_evidence`` records it), else reads it from the
    surface. Off by default: on the hard listener's scans settling them, and cutting them out with their faces, both
    took the seen parts farther from the ear (studies/stray_evidence.py)."""
    scan = surface_without_outliers(target)
    if settings.outlier_sigmas is None:
        return scan, None
    stray = stray_points(scan.vertices, settings.outlier_sigmas, settings.outlier_floor_mm, target.noise_mm)
    if stray.any():
        scan = trimesh.Trimesh(settle_strays(scan.vertices, stray), scan.faces, process=False)
    return scan, stray


def personal_detail(vertices_mm: np.ndarray, faces: np.ndarray, target: Target,
                    settings: DetailSettings | None = None) -> PersonalDetail:
    """The personal-detail layer of a posed PPM (``vertices_mm``, ``faces``: mm, project frame) on ``target``.

    A displacement field U (n, 3) minimises, per stiffness s of the schedule (stiff to supple, each a few times with
    the correspondences found again on the displaced surface),

        f sum_trusted |x_i + u_i - c_i|^2 + w sum_trusted scan points |B_j (x + u) - p_j|^2 + s tr(U^T L U) + d |U|^2,

    f the ``forward_weight``, c_i the closest point of vertex i on the scan's surface, B_j the barycentric row of scan
    point p_j's closest point on the displaced PPM (so that the scan also pulls the PPM into hollows no vertex maps
    to), L the Laplacian of :func:`laplacian`; the rim is held. Then U is bounded and halved around any folded face
    (turned against the PPM's, or creased against a neighbour beyond ``crease_limit_deg`` and the PPM's own crease
    there) until none is."""
    from scipy.sparse.linalg import factorized  # noqa: PLC0415

    settings = settings or DetailSettings.packaged()
    vertices_mm = np.asarray(vertices_mm, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if not np.isfinite(vertices_mm).all():
        raise PpmError("the posed PPM has non-finite vertices; fit it again before adding the personal detail")
    scan, stray = evidence_surface(target, settings)
    strays = None if stray is None else int(stray.sum())
    scan_points, scan_normals = np.asarray(scan.vertices), np.asarray(scan.vertex_normals)
    edge_points = boundary_samples(scan)
    scan_edge = cKDTree(edge_points) if len(edge_points) else None
    n = len(vertices_mm)
    smoothing = laplacian(vertices_mm, faces)
    taper = rim_taper(vertices_mm, faces, settings.rim_taper_mm)
    free = np.flatnonzero(taper > 0.0)
    displacement = np.zeros((n, 3))
    trusted = np.zeros(n, dtype=bool)
    def pair(mesh: trimesh.Trimesh, points_mm: np.ndarray, normals: np.ndarray):
        """Each point's closest point on ``mesh`` (on a face turned its way with ``facing_pairs``)."""
        if settings.facing_pairs:
            return closest_facing(mesh, points_mm, normals, settings.reach_mm, settings.normal_agreement_deg)
        return closest_within(mesh, points_mm, settings.reach_mm)

    noise = None
    schedule = tuple(settings.stiffness_mm2)
    if settings.noise_stiffness_factor is not None:
        noise = target.noise_mm if target.noise_mm is not None else scan_noise_mm(scan_points)
        schedule = noise_schedule(schedule, noise, settings.noise_stiffness_factor)
    roughness_cap = (None if settings.roughness_limit_deg is None
                     else surface_roughness_deg(vertices_mm, faces) + settings.roughness_limit_deg)
    stages = 0
    for stiffness in schedule:
        before = (displacement.copy(), trusted.copy())
        for _ in range(max(1, settings.iterations_per_stiffness)):
            moved = trimesh.Trimesh(vertices_mm + displacement, faces, process=False)
            closest, distance, triangle = pair(scan, moved.vertices, moved.vertex_normals)
            trusted = _trusted_pairs(moved.vertices, np.asarray(moved.vertex_normals), closest, distance,
                                     scan.face_normals[triangle], scan_edge, closest, moved.vertices, settings)
            forward = settings.forward_weight * trusted.astype(np.float64)
            system = sp.diags(forward) + stiffness * smoothing + settings.decay * sp.identity(n)
            wanted = forward[:, None] * (closest - vertices_mm)
            if settings.reverse_weight > 0:
                on_ppm, back, ppm_triangle = pair(moved, scan_points, scan_normals)
                pulling = np.flatnonzero(_trusted_pairs(scan_points, scan_normals, on_ppm, back,
                                                        moved.face_normals[ppm_triangle], scan_edge, scan_points,
                                                        on_ppm, settings))
                corners = faces[ppm_triangle[pulling]]
                weights = trimesh.triangles.points_to_barycentric(moved.vertices[corners], on_ppm[pulling])
                rows = sp.csr_matrix((weights.ravel(), (np.repeat(np.arange(len(pulling)), 3), corners.ravel())),
                                     shape=(len(pulling), n))
                system = system + settings.reverse_weight * (rows.T @ rows)
                wanted = wanted + settings.reverse_weight * (rows.T @ (scan_points[pulling] - rows @ vertices_mm))
            solve = factorized(system.tocsr()[free][:, free].tocsc())
            displacement = np.zeros((n, 3))
            for axis in range(3):
                displacement[free, axis] = solve(np.ascontiguousarray(wanted[free, axis]))
            displacement *= taper[:, None]
            if settings.evidence_fade_mm is not None:
                evidence = trusted.copy()
                if settings.reverse_weight > 0:
                    evidence[corners.ravel()] = True
                displacement *= evidence_fade(vertices_mm, evidence, settings.evidence_fade_mm)[:, None]
        if stages and roughness_cap is not None and surface_roughness_deg(vertices_mm + displacement, faces) > roughness_cap:
            displacement, trusted = before  # this stage fits the scan's noise: keep the stiffer one before it
            break
        stages += 1
    size = np.linalg.norm(displacement, axis=1)
    displacement *= np.minimum(1.0, settings.max_displacement_mm / np.maximum(size, 1e-12))[:, None]
    displacement, halvings, smoothings = unfold(vertices_mm, faces, displacement, taper <= 0.0, settings)
    return PersonalDetail(displacement_mm=displacement, trusted=trusted, halvings=halvings, stages=stages,
                          smoothings=smoothings, noise_mm=noise, stiffness_mm2=schedule[:stages], strays=strays)


def add_personal_detail(model, target: Target, settings: DetailSettings | None = None,
                        judged_on: Target | None = None) -> tuple[PersonalDetail, dict]:
    """Add the personal-detail layer of ``model`` (a :class:`ppm.model.PinnaModel` posed by a fit) on ``target``
    (its evidence: best the whole scan the fit's target was cut from) as its shape key :data:`DETAIL_KEY` at weight
    1; returns the layer and a summary (the scan -> pinna distances without and with it, mm, over ``judged_on``, e.g.
    the fit's segmented target, or ``target``; the layer's figures)."""
    from .report import distance_summary, one_sided_distances_mm  # noqa: PLC0415

    if model.detail_weight:
        model.set_detail_weight(0.0)
    posed = model.evaluate()
    detail = personal_detail(posed, model.faces, target, settings)
    mismatch = model.set_personal_detail(detail.displacement_mm, 1.0)
    with_detail = model.evaluate()
    judged_on = judged_on or target
    summary = {"ppm": distance_summary(one_sided_distances_mm(judged_on, posed, model.faces)),
               "ppm_detail": distance_summary(one_sided_distances_mm(judged_on, with_detail, model.faces)),
               "layer": detail.summary(), "shape_key": DETAIL_KEY, "shape_key_mismatch_mm": round(mismatch, 6),
               # faces crossing another, of the fit and of the layered pinna: the fit's sheet barrier keeps the
               # template's facing sheets apart, the layer has no such term (pulled towards the raw scan alone it
               # can cross them; with the reconstruction's fill as evidence it drew them onto one sheet)
               "self_intersecting_faces": {"ppm": len(self_intersecting_faces(posed, model.faces)),
                                           "ppm_detail": len(self_intersecting_faces(with_detail, model.faces))},
               "settings": dataclasses.asdict(settings or DetailSettings.packaged())}
    return detail, summary
