"""Vertex weights of the bones and displacement fields of the shape keys, computed on the template.

Frame: millimetres, +x front, +y left, +z up. Everything here is NumPy; `ppm.rig` hands the
results to Blender. Weights fall off smoothly with the geodesic distance from each bendy bone's
anatomical curve; where curves overlap their weights are normalised to sum to at most 1, and a
static root bone takes the rest, so every vertex is fully weighted and there are no seams (the
parent bone then moves everything as one affine map, see `ppm.rig`). Each shape
key is a smooth, local displacement: along the vertex normal (depths, creases, dents, forms), or
radially away from an axis (ear-canal diameter). The normals used are smoothed over the key's
radius, so a key moves a region as a whole. Regions, radii and amplitudes are data in
`ppm/data/rig.yaml`.
"""
from __future__ import annotations

import dataclasses
from functools import lru_cache
from importlib import resources

import numpy as np
import trimesh
import yaml

from .errors import PpmError
from .geodesic import distance_from, edge_graph, path_through


@lru_cache(maxsize=1)
def rig_layout() -> dict:
    """The parsed `ppm/data/rig.yaml`: curve paths, radii and shape-key regions by landmark name."""
    return yaml.safe_load(resources.files("ppm").joinpath("data/rig.yaml").read_text(encoding="utf-8"))


def falloff(t: np.ndarray) -> np.ndarray:
    """Smooth bump: 1 at t = 0, 0 for t >= 1, zero slope at both ends: (1 - t²)²."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    return (1.0 - t * t) ** 2


@dataclasses.dataclass(frozen=True)
class CurveGeometry:
    """Rest geometry of one bendy bone: its surface path (vertex ids), head and tail (mm), end tangents."""

    name: str
    path: np.ndarray
    head_mm: np.ndarray
    tail_mm: np.ndarray
    tangent_start: np.ndarray
    tangent_end: np.ndarray


@dataclasses.dataclass(frozen=True)
class RigGeometry:
    """Everything Blender needs besides the template: bones, weights and shape-key displacements.

    weights : (n, 10) float, columns in the order of `weight_names` (the 9 bendy bones, then the static
    root bone of the curve armature, which holds the remainder); rows sum to 1. shape_key_offsets_mm : (18, n, 3) float, displacement at weight 1.
    """

    parent_head_mm: np.ndarray
    curves: tuple[CurveGeometry, ...]
    weight_names: tuple[str, ...]
    weights: np.ndarray
    shape_key_names: tuple[str, ...]
    shape_key_offsets_mm: np.ndarray


def _landmark_ids(landmarks: dict[str, int], names: list[str], owner: str) -> list[int]:
    missing = [name for name in names if name not in landmarks]
    if missing:
        raise PpmError(f"{owner} refers to unknown landmark(s) {missing}; define them in the template's landmarks.yaml")
    return [int(landmarks[name]) for name in names]


def _tangent(points_mm: np.ndarray, at_start: bool, span_mm: float = 6.0) -> np.ndarray:
    """Unit tangent of a polyline at its start (pointing inward) or end (pointing onward)."""
    seq = points_mm if at_start else points_mm[::-1]
    run = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(seq, axis=0), axis=1))]
    far = seq[min(int(np.searchsorted(run, span_mm)), len(seq) - 1)]
    direction = far - seq[0] if at_start else seq[0] - far
    norm = np.linalg.norm(direction)
    if norm == 0:
        raise PpmError("a curve path has zero length; its landmarks coincide")
    return direction / norm


def curve_geometry(vertices_mm: np.ndarray, graph, landmarks: dict[str, int]) -> tuple[CurveGeometry, ...]:
    """Surface paths and rest bones of the 9 curves from their landmark lists in rig.yaml."""
    curves = []
    for name, spec in rig_layout()["curves"].items():
        ids = _landmark_ids(landmarks, spec["path"], f"curve {name}")
        path = path_through(graph, ids)
        points = vertices_mm[path]
        curves.append(CurveGeometry(name, path, points[0].copy(), points[-1].copy(),
                                    _tangent(points, True), _tangent(points, False)))
    return tuple(curves)


def bone_weights(vertices_mm: np.ndarray, graph, curves: tuple[CurveGeometry, ...]) -> np.ndarray:
    """(n, 10) weights: 9 bendy bones (smooth geodesic fall-off, normalised where they overlap) + remainder."""
    radii = {name: float(spec["radius_mm"]) for name, spec in rig_layout()["curves"].items()}
    raw = np.stack([falloff(distance_from(graph, c.path) / radii[c.name]) for c in curves], axis=1)
    total = raw.sum(axis=1, keepdims=True)
    raw = np.where(total > 1.0, raw / np.maximum(total, 1e-12), raw)
    return np.concatenate([raw, 1.0 - raw.sum(axis=1, keepdims=True)], axis=1)


def smoothed_normals(graph, normals: np.ndarray, scale_mm: float) -> np.ndarray:
    """Unit vertex normals diffused over the edge graph to a smoothing scale of about `scale_mm`."""
    from scipy.sparse import diags, identity

    adjacency = (graph > 0).astype(np.float64) + identity(graph.shape[0], format="csr")
    step = diags(1.0 / np.asarray(adjacency.sum(axis=1)).ravel()) @ adjacency
    edge_mm = float(np.median(graph.data))
    field = np.asarray(normals, dtype=np.float64)
    for _ in range(int(min(200, round((scale_mm / edge_mm) ** 2)))):
        field = step @ field
    return field / np.maximum(np.linalg.norm(field, axis=1, keepdims=True), 1e-12)


def shape_key_offsets(mesh: trimesh.Trimesh, graph, landmarks: dict[str, int],
                      names: list[str]) -> np.ndarray:
    """(len(names), n, 3) displacement in mm of every shape key at weight 1."""
    specs = rig_layout()["shape_keys"]
    normals = np.asarray(mesh.vertex_normals, dtype=np.float64)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    offsets = np.zeros((len(names), len(vertices), 3))
    for k, name in enumerate(names):
        if name not in specs:
            raise PpmError(f"shape key {name!r} has no region in rig.yaml")
        spec = specs[name]
        path = path_through(graph, _landmark_ids(landmarks, spec["path"], f"shape key {name}"))
        profile = falloff(distance_from(graph, path) / float(spec["radius_mm"]))
        if spec["kind"] == "normal":
            # the normal field smoothed over about the key's radius: a narrow groove (scapha) deepens
            # as a whole instead of its walls folding into each other
            direction = smoothed_normals(graph, normals, float(spec["radius_mm"]))
        elif spec["kind"] == "radial":
            a = vertices[_landmark_ids(landmarks, [spec["axis_point"]], f"shape key {name}")[0]]
            axis = np.asarray(spec["axis_direction"], dtype=np.float64)
            axis = axis / np.linalg.norm(axis)
            radial = (vertices - a) - np.outer((vertices - a) @ axis, axis)
            r = np.linalg.norm(radial, axis=1, keepdims=True)
            core = float(spec["core_radius_mm"])  # the canal floor near the axis stretches, it is not torn
            direction = radial / np.maximum(r, 1e-9) * (r * r / (r * r + core * core))
        else:
            raise PpmError(f"shape key {name!r}: kind must be 'normal' or 'radial', got {spec['kind']!r}")
        field = profile[:, None] * direction
        # amplitude_mm is the largest displacement of the key at weight 1
        offsets[k] = float(spec["amplitude_mm"]) * field / np.linalg.norm(field, axis=1).max()
    return offsets


def rig_geometry(vertices_mm: np.ndarray, faces: np.ndarray, landmarks: dict[str, int],
                 shape_key_names: list[str]) -> RigGeometry:
    """All rig data for a template in correspondence with `landmarks` (vertex ids)."""
    mesh = trimesh.Trimesh(vertices_mm, faces, process=False)
    graph = edge_graph(np.asarray(vertices_mm, np.float64), np.asarray(faces))
    curves = curve_geometry(np.asarray(vertices_mm, np.float64), graph, landmarks)
    weights = bone_weights(vertices_mm, graph, curves)
    parent_head = np.asarray(vertices_mm, np.float64)[_landmark_ids(landmarks, [rig_layout()["parent"]["head"]],
                                                                    "parent bone")[0]]
    names = tuple(f"{c.name}-Bendy" for c in curves) + (rig_layout()["parent"]["root_bone"],)
    offsets = shape_key_offsets(mesh, graph, landmarks, shape_key_names)
    return RigGeometry(parent_head, curves, names, weights, tuple(shape_key_names), offsets)
