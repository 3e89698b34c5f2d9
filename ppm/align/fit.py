"""Automatic alignment of the PPM to a pinna scan: robust global pose, then staged fitting of all
144 parameters (millimetres, degrees, project frame).

Objective, minimised by damped Gauss-Newton on the parameters normalised to their ranges:

* target -> model: for every target point, the point-to-plane distance to its closest point on the
  deformed template surface (the surface, not its vertices), Huber-weighted, trimmed beyond
  `trim_mm` (outliers, skin the template does not cover);
* model -> target: for every template vertex away from the template's outer ring, the
  point-to-plane distance to its closest target point, trimmed the same way (holes), so the model
  cannot shrink into a part of the scan;
* a weak prior pulling each parameter towards its default, in units of its range;
* a fold barrier: every triangle whose normal turned more than 60° from the template's costs the
  square of how far past 60° it is (in cosine), so wide bone ranges cannot fold the surface over;
* a sheet barrier: where the template folds over itself (helix over scapha, the two faces of the helix rim), a
  vertex pressing nearer than a fraction of a millimetre to the facing sheet, or through it, costs the square of
  the shortfall (:mod:`ppm.align.sheets`), so the fit cannot pass through itself where the scan has holes.

The Jacobian of the vertices with respect to the active parameters is taken by finite differences
of Blender's evaluation (about 2 ms per parameter). Stages follow the manual protocol: the parent
bone (global pose and size), then all bones (convex structures), then the shape keys (concave
structures), then everything together until the cost stops falling. Bounds are kept by an active
set (a parameter at a bound that the step pushes outward is held there) and clipping.

The cost has many minima a few per cent apart (144 parameters, several of which trade off against each
other on a real ear), and which one a large Gauss-Newton step lands in depends on floating-point noise:
the same crop fitted in two poses, or on two CPUs, ended 0.25 mm apart. So the staged fit is followed by
`restarts` rounds of basin hopping: the best parameters so far, all but the parent bone's nudged by a
seeded normal spread of `restart_spread` range units, are fitted again with everything free, and the
lowest cost wins. The nudges are the same in every pose (they act on the parent-relative parameters).
"""
from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np
from scipy.spatial import cKDTree
from trimesh.registration import icp

from ..geodesic import distance_from_rim_mm
from ..model import PinnaModel
from ..parameters import PinnaParameters, bounds, parameter_specs
from .pose import parent_pose_from_rigid, rotation_zyx
from .sheets import facing_sheets, sheet_terms
from .surface import OneRingSurface
from .target import Target

log = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class AlignSettings:
    """Settings of :func:`align` (lengths in mm)."""

    max_target_points: int = 6000       # target points used while fitting (all are used for the report)
    trim_mm: float = 5.0                # correspondences farther apart are ignored
    huber_mm: float = 2.0               # residuals above this are down-weighted
    model_to_target_weight: float = 0.25
    prior_weight: float = 2e-3          # per parameter, in (range units)^2 against mm^2 of residual
    fold_cosine: float = 0.5            # a face whose normal turns more than 60° from the template's ...
    fold_weight: float = 0.1            # ... costs fold_weight * (fold_cosine - cos(turn))^2 (barrier against folds;
    #                                     1.0 held P143's cymba conchae 1.27 mm too shallow, 0.1 fits it to 0.55 mm
    #                                     with no face folded: benchmarks/align_real.py --fold-weight)
    sheet_weight: float = 0.01          # a vertex pressing on a facing sheet costs sheet_weight * shortfall^2 (mm^2)
    sheet_margin_mm: float = 0.3        # ... the clearance kept from it (half the template's where that is less)
    ring_exclusion_mm: float = 4.0      # template vertices this close to its outer ring are not pulled
    normal_min_cosine: float | None = None  # scan -> model pairs whose normals meet at a cosine below this are ignored
    start_angles_deg: tuple[float, ...] = (0.0, 15.0, -15.0)
    stages: tuple[tuple[str, int], ...] = (("parent", 10), ("bones", 12), ("shape_keys", 8), ("all", 20))
    relative_tolerance: float = 2e-3
    restarts: int = 4                   # basin-hopping rounds after the staged fit (0: none)
    restart_spread: float = 0.05        # their nudge: standard deviation in range units, parent bone excluded
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0.0 <= self.fold_cosine < 1.0:  # the barrier must start before a face folds (cos 0)
            raise ValueError(f"fold_cosine must be in [0, 1), got {self.fold_cosine}")
        if self.restarts < 0 or self.restart_spread < 0.0:
            raise ValueError(f"restarts and restart_spread must not be negative, got {self.restarts}, "
                             f"{self.restart_spread}")


@dataclasses.dataclass
class AlignmentResult:
    """What :func:`align` found: parameters, aligned vertices (mm), the cost history and timings."""

    parameters: PinnaParameters
    vertices_mm: np.ndarray
    history: list[dict]
    seconds: float
    start_index: int
    warnings: list[str]
    folded_faces: int = 0
    sheet_pairs_pressing: int = 0       # facing-sheet pairs nearer than their margin (ppm.align.sheets; 0 without it)


def _stage_mask(stage: str) -> np.ndarray:
    specs = parameter_specs()
    parent = np.array([s.target == "Size-Bendy" for s in specs])
    shape = np.array([s.kind == "shape_key" for s in specs])
    if stage == "parent":
        return parent
    if stage == "bones":
        return ~shape
    if stage == "shape_keys":
        return shape | parent
    if stage == "all":
        return np.ones(len(specs), dtype=bool)
    raise ValueError(f"unknown stage {stage!r}")


class _Problem:
    """Residuals and their Jacobian for one target, with the model's parameters as the unknowns."""

    def __init__(self, model: PinnaModel, target: Target, settings: AlignSettings):
        self.model = model
        self.settings = settings
        rng = np.random.default_rng(settings.seed)
        points = target.points_mm
        if len(points) > settings.max_target_points:
            pick = np.sort(rng.choice(len(points), settings.max_target_points, replace=False))
            points = points[pick]
            normals = target.normals[pick]
        else:
            normals = target.normals
        self.points = points
        self.target_normals = normals
        self.target_tree = cKDTree(target.points_mm)
        self.all_points = target.points_mm
        self.all_normals = target.normals
        self.surface = OneRingSurface(model.faces, len(model.template_vertices_mm))
        # template vertices well inside the outer skin ring take part in the model -> target term
        self.inner = np.flatnonzero(distance_from_rim_mm(model.template_vertices_mm, model.faces)
                                    > settings.ring_exclusion_mm)
        specs = parameter_specs()
        self.default = np.array([s.default for s in specs])
        self.lower, self.upper = bounds()
        self.scale = np.maximum(self.upper - self.default, self.default - self.lower)
        self.step = 0.02 * self.scale  # finite-difference step per parameter
        self.rest_normals = model.rest_face_normals
        self.sheets = (facing_sheets(model.template_vertices_mm, model.faces, margin_mm=settings.sheet_margin_mm)
                       if settings.sheet_weight > 0 else None)

    def residuals(self, vertices: np.ndarray, with_geometry: bool = False):
        """Weighted residual vectors (mm) of both terms, and what is needed for their Jacobians."""
        s = self.settings
        face_ids, bary, distance = self.surface.closest(vertices, self.points)
        tri = vertices[self.model.faces[face_ids]]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        on_surface = np.einsum("ij,ijk->ik", bary, tri)
        r_a = np.einsum("ij,ij->i", on_surface - self.points, normal)
        keep_a = distance < s.trim_mm
        if s.normal_min_cosine is not None:  # a scan point facing away from its closest surface (a cavity's far wall)
            keep_a &= np.einsum("ij,ij->i", normal, self.target_normals) > s.normal_min_cosine
        d_b, j = self.target_tree.query(vertices[self.inner])
        n_b = self.all_normals[j]
        r_b = np.einsum("ij,ij->i", vertices[self.inner] - self.all_points[j], n_b)
        keep_b = d_b < s.trim_mm
        w_a = keep_a * np.minimum(1.0, s.huber_mm / np.maximum(np.abs(r_a), 1e-12)) / max(keep_a.sum(), 1)
        w_b = keep_b * np.minimum(1.0, s.huber_mm / np.maximum(np.abs(r_b), 1e-12)) / max(keep_b.sum(), 1)
        w_b = w_b * s.model_to_target_weight
        fold_faces, r_f, dcos_dv = self.fold_terms(vertices)
        pressing, r_s, n_s = self.sheet_terms(vertices)
        cost = float((w_a * r_a**2).sum() + (w_b * r_b**2).sum() + s.fold_weight * (r_f**2).sum()
                     + s.sheet_weight * (r_s**2).sum())
        # a fold (cos < 0) is a turned face (fold_cosine >= 0) whose residual exceeds fold_cosine
        stats = {"median_mm": float(np.median(distance)), "kept_share": float(keep_a.mean()),
                 "folded_faces": int((r_f > s.fold_cosine).sum()), "pressing_pairs": int(len(pressing))}
        if not with_geometry:
            return cost, stats
        return cost, stats, (face_ids, bary, normal, r_a, w_a, n_b, r_b, w_b, fold_faces, r_f, dcos_dv,
                             pressing, r_s, n_s)

    def sheet_terms(self, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The facing-sheet pairs pressing too close, their residuals (mm) and plane normals (none without the
        barrier); see :func:`ppm.align.sheets.sheet_terms`."""
        if self.sheets is None:
            return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, 3))
        return sheet_terms(self.sheets, vertices, self.model.faces)

    def fold_terms(self, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Faces turned past the fold threshold, their residuals (fold_cosine - cos(turn), so a
        positive residual means too far turned) and the derivative of cos(turn) by their three
        vertices, (m, 3, 3) per mm."""
        faces = self.model.faces
        tri = vertices[faces]
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        normal = np.cross(e1, e2)
        length = np.maximum(np.linalg.norm(normal, axis=1), 1e-12)
        unit = normal / length[:, None]
        cosine = np.einsum("ij,ij->i", unit, self.rest_normals)
        turned = np.flatnonzero(cosine < self.settings.fold_cosine)
        unit, m, c = unit[turned], self.rest_normals[turned], cosine[turned]
        g = (m - c[:, None] * unit) / length[turned, None]     # d cos / d normal
        d1 = np.cross(e2[turned], g)
        d2 = np.cross(g, e1[turned])
        dcos_dv = np.stack([-(d1 + d2), d1, d2], axis=1)
        return turned, self.settings.fold_cosine - c, dcos_dv

    def total_cost(self, params: np.ndarray) -> float:
        """The objective at `params`: residual terms, fold barrier and prior."""
        return self.residuals(self.model.evaluate(PinnaParameters(params)))[0] + self.prior(params)

    def prior(self, params: np.ndarray) -> float:
        u = (params - self.default) / self.scale
        return float(self.settings.prior_weight * (u * u).sum())

    def jacobian(self, params: np.ndarray, vertices: np.ndarray, active: np.ndarray) -> np.ndarray:
        """(n, 3, k) derivative of the vertices (mm) with respect to the k active parameters
        (per unit of normalised parameter), by forward differences of Blender's evaluation."""
        columns = np.flatnonzero(active)
        jac = np.empty((len(vertices), 3, len(columns)))
        for c, index in enumerate(columns):
            probe = params.copy()
            h = self.step[index] if params[index] + self.step[index] <= self.upper[index] else -self.step[index]
            probe[index] += h
            jac[:, :, c] = (self.model.evaluate(PinnaParameters(probe)) - vertices) * (self.scale[index] / h)
        return jac


def _gauss_newton_stage(problem: _Problem, params: np.ndarray, active: np.ndarray, iterations: int,
                        history: list[dict], stage: str) -> np.ndarray:
    s = problem.settings
    vertices = problem.model.evaluate(PinnaParameters(params))
    cost, stats, geometry = problem.residuals(vertices, with_geometry=True)
    cost += problem.prior(params)
    damping = 1e-3
    for iteration in range(iterations):
        face_ids, bary, normal, r_a, w_a, n_b, r_b, w_b, fold_faces, r_f, dcos_dv, pressing, r_s, n_s = geometry
        jac = problem.jacobian(params, vertices, active)
        faces = problem.model.faces[face_ids]
        rows_a = sum(bary[:, k, None] * np.einsum("ij,ijk->ik", normal, jac[faces[:, k]]) for k in range(3))
        rows_b = np.einsum("ij,ijk->ik", n_b, jac[problem.inner])
        u = (params - problem.default) / problem.scale
        hessian = (rows_a.T * w_a) @ rows_a + (rows_b.T * w_b) @ rows_b
        gradient = (rows_a.T * w_a) @ r_a + (rows_b.T * w_b) @ r_b
        if len(fold_faces):  # residual fold_cosine - cos: its rows are minus the derivative of cos
            corners = problem.model.faces[fold_faces]
            rows_f = -sum(np.einsum("ij,ijk->ik", dcos_dv[:, k], jac[corners[:, k]]) for k in range(3))
            hessian += s.fold_weight * rows_f.T @ rows_f
            gradient += s.fold_weight * rows_f.T @ r_f
        if len(pressing):  # residual margin - side * (v_i - v_j) . n_j, the normal held
            i, j = problem.sheets.i[pressing], problem.sheets.j[pressing]
            side = problem.sheets.side[pressing]
            rows_s = -side[:, None] * np.einsum("ij,ijk->ik", n_s, jac[i] - jac[j])
            hessian += s.sheet_weight * rows_s.T @ rows_s
            gradient += s.sheet_weight * rows_s.T @ r_s
        hessian += s.prior_weight * np.eye(len(gradient))
        gradient += s.prior_weight * u[active]
        # parameters held at a bound that the descent direction pushes outward stay there (active set)
        lower, upper = problem.lower[active], problem.upper[active]
        tolerance = 1e-9 * problem.scale[active]
        held = ((params[active] <= lower + tolerance) & (gradient > 0)) | \
               ((params[active] >= upper - tolerance) & (gradient < 0))
        free = ~held
        accepted = False
        for _ in range(6):
            system = hessian + damping * np.diag(np.diag(hessian) + 1e-9)
            delta = np.zeros_like(gradient)
            delta[free] = -np.linalg.solve(system[np.ix_(free, free)], gradient[free])
            trial = params.copy()
            trial[active] = np.clip(params[active] + delta * problem.scale[active], lower, upper)
            trial_vertices = problem.model.evaluate(PinnaParameters(trial))
            trial_cost, trial_stats, trial_geometry = problem.residuals(trial_vertices, with_geometry=True)
            trial_cost += problem.prior(trial)
            if trial_cost < cost:
                accepted = True
                improvement = (cost - trial_cost) / cost
                params, vertices, cost, stats, geometry = trial, trial_vertices, trial_cost, trial_stats, trial_geometry
                damping = max(damping / 3.0, 1e-6)
                break
            damping *= 8.0
        history.append({"stage": stage, "iteration": iteration, "cost": cost, **stats, "accepted": accepted})
        log.info("%-10s it %2d cost %.4f median %.3f mm%s", stage, iteration, cost, stats["median_mm"],
                 "" if accepted else " (no descent)")
        if not accepted or improvement < s.relative_tolerance:
            break
    return params


def _basin_hopping(problem: _Problem, params: np.ndarray, iterations: int, history: list[dict]) -> np.ndarray:
    """`settings.restarts` refits with everything free from the best parameters so far, nudged by a seeded
    normal spread (range units) on all but the parent bone; returns the lowest-cost parameters."""
    s = problem.settings
    rng = np.random.default_rng(s.seed + 1)
    nudged = ~_stage_mask("parent")
    everything = _stage_mask("all")
    best, best_cost = params, problem.total_cost(params)
    for restart in range(s.restarts):
        start = best + rng.normal(0.0, s.restart_spread, len(best)) * nudged * problem.scale
        start = np.clip(start, problem.lower, problem.upper)
        candidate = _gauss_newton_stage(problem, start, everything, iterations, history, f"restart {restart + 1}")
        cost = problem.total_cost(candidate)
        log.info("restart %d: cost %.4f (best so far %.4f)", restart + 1, cost, best_cost)
        if cost < best_cost:
            best, best_cost = candidate, cost
    return best


def _start_rotations(angles_deg: tuple[float, ...]) -> list[np.ndarray]:
    starts = [np.eye(3)]
    for angle in angles_deg:
        if angle == 0.0:
            continue
        for axis in range(3):
            euler = np.zeros(3)
            euler[axis] = angle
            starts.append(rotation_zyx(euler))
    return starts


def global_pose(model: PinnaModel, target: Target, settings: AlignSettings) -> tuple[PinnaParameters, int, list[str]]:
    """Rigid pose of the template on the target by ICP from several starts; the best becomes the
    parent bone's location and rotation. Returns the parameters, the winning start and warnings."""
    rest = model.template_vertices_mm
    head = model.rig.parent_head_mm if model.rig is not None else rest.mean(axis=0)
    template_centre = rest.mean(axis=0)
    target_centre = target.points_mm.mean(axis=0)
    tree = cKDTree(target.points_mm)
    best = (np.inf, None, -1)
    for index, rotation in enumerate(_start_rotations(settings.start_angles_deg)):
        initial = np.eye(4)
        initial[:3, :3] = rotation
        initial[:3, 3] = target_centre - rotation @ template_centre
        matrix, moved, _ = icp(rest, target.points_mm, initial=initial, threshold=1e-5, max_iterations=40,
                               reflection=False, scale=False)
        distance = tree.query(moved)[0]
        score = float(np.mean(np.minimum(distance, settings.trim_mm) ** 2))
        log.info("start %d: trimmed mean squared distance %.3f mm^2", index, score)
        if score < best[0]:
            best = (score, matrix, index)
    values = parent_pose_from_rigid(best[1], head)
    params = PinnaParameters.from_dict(values, out_of_range="clip")
    warnings = [f"{name} = {value:.1f} is outside its range and was clamped; is the scan in the project frame? "
                "If not, prepare it with scan_pose 'any' (config align.scan_pose, ppm align --scan-pose any)"
                for name, value in values.items() if params[name] != value]
    return params, best[2], warnings


def align(model: PinnaModel, target: Target, settings: AlignSettings | None = None) -> AlignmentResult:
    """Fit all 144 PPM parameters to `target`; see the module docstring for the objective."""
    settings = settings or AlignSettings()
    start = time.perf_counter()
    params, start_index, warnings = global_pose(model, target, settings)
    problem = _Problem(model, target, settings)
    vector = params.to_vector()
    history: list[dict] = []
    for stage, iterations in settings.stages:
        vector = _gauss_newton_stage(problem, vector, _stage_mask(stage), iterations, history, stage)
    if settings.stages:
        vector = _basin_hopping(problem, vector, settings.stages[-1][1], history)
    final = PinnaParameters(vector)
    vertices = model.evaluate(final)
    folded = len(model.folded_faces(vertices))
    if folded:
        warnings.append(f"{folded} triangles of the aligned pinna are folded over (normal turned > 90°); "
                        "fix them by hand in the .blend before stitching")
    return AlignmentResult(final, vertices, history, time.perf_counter() - start, start_index,
                           warnings + list(target.warnings), folded, len(problem.sheet_terms(vertices)[0]))
