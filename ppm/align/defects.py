"""Defective scans of real ears: a clean crop (the ground truth) as a scanner or phone app would deliver it.

Graded levels (`ppm/data/scan_defects.yaml`): occlusion holes where a scanner does not see (deep cavum
conchae, behind the helix rim, under the antihelix folds: found by ray casting from the scanner's views,
not placed by hand), coarser sampling, noise along the normals, outliers and spikes, a partial crop; then
any rigid pose (uniform random rotation, an offset), a unit other than millimetres and, on request, a
mirror image (a right ear). The clean crop is in millimetres, project frame (x front, y left, z up).
"""
from __future__ import annotations

import dataclasses
from functools import lru_cache
from importlib import resources

import numpy as np
import trimesh
import yaml
from scipy.spatial.transform import Rotation

from ..errors import PpmError
from ..template.segment import crop_to_region
from .pose import apply_similarity
from .synthetic import add_scan_defects


@lru_cache(maxsize=1)
def defect_settings() -> dict:
    """The parsed `ppm/data/scan_defects.yaml` (levels and pose ranges)."""
    return yaml.safe_load(resources.files("ppm").joinpath("data/scan_defects.yaml").read_text(encoding="utf-8"))


def levels() -> list[str]:
    """Defect levels from the lightest to the hardest."""
    return list(defect_settings()["levels"])


def kinds() -> list[str]:
    """Other kinds of scan beside the graded levels (``smooth``: a photogrammetry scan's flattened ridges and
    filled cavities), each also a name :func:`defective_scan` takes as its level."""
    return list(defect_settings().get("kinds") or {})


def recipe_of(level: str) -> dict:
    """The defects of a level or kind: a kind's base level with its own additions (``laplacian``)."""
    settings = defect_settings()
    if level in settings["levels"]:
        return dict(settings["levels"][level])
    if level in (settings.get("kinds") or {}):
        kind = dict(settings["kinds"][level])
        return {**settings["levels"][kind.pop("base")], **kind}
    raise PpmError(f"unknown defect level {level!r}; use one of {levels() + kinds()}")


def smoothed(mesh: trimesh.Trimesh, iterations: int, lamb: float) -> trimesh.Trimesh:
    """A copy of ``mesh`` (mm) after ``iterations`` steps of umbrella-operator Laplacian smoothing of weight ``lamb``
    (trimesh.smoothing.filter_laplacian): ridges sink, cavities fill, as a photogrammetry scan shows an ear."""
    out = trimesh.Trimesh(np.asarray(mesh.vertices).copy(), np.asarray(mesh.faces).copy(), process=False)
    trimesh.smoothing.filter_laplacian(out, lamb=float(lamb), iterations=int(iterations), volume_constraint=False)
    return out


@dataclasses.dataclass(frozen=True)
class DefectiveScan:
    """A defective, posed copy of a clean crop.

    mesh : the scan as delivered (file units, any pose).
    truth_to_scan : (4, 4) similarity (rotation times the unit's scale, possibly a reflection, and an
        offset) that maps the clean crop's millimetre head frame onto the scan's frame.
    level, unit, mirrored : what was applied.
    kept_share : share of the clean crop's area the scanner saw (before resampling).
    """

    mesh: trimesh.Trimesh
    truth_to_scan: np.ndarray
    level: str
    unit: str
    mirrored: bool
    kept_share: float


def scanner_views(count: int, cone_deg: float) -> np.ndarray:
    """(count + 1, 3) unit view directions (from the ear towards the scanner): the lateral axis +y and
    `count` directions evenly spaced on a cone of `cone_deg` half-angle around it."""
    azimuth = 2.0 * np.pi * np.arange(count) / max(count, 1)
    cone = np.deg2rad(cone_deg)
    ring = np.stack([np.sin(cone) * np.cos(azimuth), np.full(count, np.cos(cone)), np.sin(cone) * np.sin(azimuth)], 1)
    return np.vstack([[0.0, 1.0, 0.0], ring])


def visible_vertices(mesh: trimesh.Trimesh, views: np.ndarray, grazing_deg: float) -> np.ndarray:
    """Boolean per vertex: seen by at least one view direction, i.e. facing it within `grazing_deg` of
    the normal and with no surface between the vertex and the scanner (ray cast, mm)."""
    normals = np.asarray(mesh.vertex_normals)
    origins = mesh.vertices + 0.05 * normals  # off the surface, so the ray does not hit its own faces
    seen = np.zeros(len(mesh.vertices), dtype=bool)
    limit = np.cos(np.deg2rad(grazing_deg))
    for view in views:
        facing = np.flatnonzero(~seen & (normals @ view > limit))
        if len(facing):
            blocked = mesh.ray.intersects_any(origins[facing], np.tile(view, (len(facing), 1)))
            seen[facing[~blocked]] = True
    return seen


def resample(mesh: trimesh.Trimesh, spacing_mm: float) -> trimesh.Trimesh:
    """Coarser sampling: vertex clustering on a `spacing_mm` grid (pymeshlab); 0 returns the mesh."""
    if spacing_mm <= 0:
        return mesh
    import pymeshlab  # noqa: PLC0415  (after bpy in one process)

    meshes = pymeshlab.MeshSet()
    meshes.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.vertices, face_matrix=mesh.faces))
    meshes.meshing_decimation_clustering(threshold=pymeshlab.PureValue(spacing_mm))
    meshes.meshing_remove_unreferenced_vertices()
    out = meshes.current_mesh()
    return trimesh.Trimesh(out.vertex_matrix(), canonical_faces(out.face_matrix()), process=False)


def canonical_faces(faces: np.ndarray) -> np.ndarray:
    """The same triangles (same winding) in one order: each starts at its smallest vertex index, and the rows are
    sorted. MeshLab's clustering returns its faces in an order that differs from run to run, so a scan drawn
    with a fixed seed would otherwise differ in its file (and in what a fit sees first) though not in shape."""
    faces = np.asarray(faces, dtype=np.int64)
    start = np.argmin(faces, axis=1)
    rolled = faces[np.arange(len(faces))[:, None], (start[:, None] + np.arange(3)) % 3]
    return rolled[np.lexsort(rolled.T[::-1])]


def cut_partially(mesh: trimesh.Trimesh, share: float, rng: np.random.Generator) -> trimesh.Trimesh:
    """The mesh without `share` of its extent on one side (a direction drawn in the side view, x-z)."""
    if share <= 0:
        return mesh
    angle = rng.uniform(0.0, 2.0 * np.pi)
    direction = np.array([np.cos(angle), 0.0, np.sin(angle)])
    along = mesh.vertices @ direction
    limit = along.max() - share * np.ptp(along)
    return crop_to_region(mesh, along <= limit)


def add_spikes(mesh: trimesh.Trimesh, share: float, rng: np.random.Generator) -> trimesh.Trimesh:
    """A copy with `share` of the vertices pushed 2-6 mm along their normals, in or out (scanner spikes)."""
    vertices = mesh.vertices.copy()
    spiked = rng.random(len(vertices)) < share
    push = rng.uniform(2.0, 6.0, int(spiked.sum())) * rng.choice([-1.0, 1.0], int(spiked.sum()))
    vertices[spiked] += push[:, None] * mesh.vertex_normals[spiked]
    return trimesh.Trimesh(vertices, mesh.faces, process=False)


def random_pose(rng: np.random.Generator, unit: str = "mm", mirrored: bool = False,
                offset_mm: float | None = None) -> np.ndarray:
    """(4, 4) similarity from the millimetre head frame to a scan frame: a uniform random rotation, the
    `unit`'s scale (file units per mm), an offset up to `offset_mm` and, if `mirrored`, a reflection (y -> -y
    before the rotation: a right ear)."""
    settings = defect_settings()["pose"]
    if unit not in settings["units"]:
        raise PpmError(f"unknown unit {unit!r}; use one of {sorted(settings['units'])}")
    scale = float(settings["units"][unit])
    offset = settings["offset_mm"] if offset_mm is None else offset_mm
    matrix = np.eye(4)
    linear = Rotation.random(random_state=rng).as_matrix()
    if mirrored:
        linear = linear @ np.diag([1.0, -1.0, 1.0])
    matrix[:3, :3] = scale * linear
    direction = rng.normal(size=3)
    matrix[:3, 3] = scale * offset * rng.uniform(0.0, 1.0) * direction / np.linalg.norm(direction)
    return matrix


def defective_scan(clean: trimesh.Trimesh, level: str, rng: np.random.Generator, *, posed: bool = True,
                   unit: str = "mm", mirrored: bool = False) -> DefectiveScan:
    """The clean crop (mm, head frame) with the defects of `level`; with `posed`, in a random pose and
    `unit` (else in the head frame, millimetres, `unit` and `mirrored` ignored)."""
    recipe = recipe_of(level)
    scanner = recipe["scanner"]
    seen = visible_vertices(clean, scanner_views(scanner["views"], scanner["cone_deg"]), scanner["grazing_deg"])
    scan = crop_to_region(clean, seen)
    kept_share = float(scan.area / clean.area)
    scan = cut_partially(scan, recipe["partial_crop_share"], rng)
    if "laplacian" in recipe:  # a photogrammetry scan: smoothed before it is sampled and noised
        scan = smoothed(scan, recipe["laplacian"]["iterations"], recipe["laplacian"]["lambda"])
    scan = resample(scan, recipe["resample_mm"])
    scan = add_scan_defects(scan, rng, noise_mm=recipe["noise_mm"], holes=0, outlier_share=recipe["outlier_share"])
    scan = add_spikes(scan, recipe["spike_share"], rng)
    matrix = random_pose(rng, unit, mirrored) if posed else np.eye(4)
    return DefectiveScan(apply_similarity(scan, matrix), matrix, level, unit if posed else "mm",
                         bool(posed and mirrored), kept_share)


def subject_seed(subject: str, seed: int) -> list[int]:
    """A seed sequence for one subject's fixed draw: the same scan on every machine, another for each subject."""
    import zlib  # noqa: PLC0415

    return [int(seed), zlib.crc32(subject.encode("utf-8"))]


def hard_scan_of(crop_path, subject: str, level: str, seed: int) -> tuple[trimesh.Trimesh, dict]:
    """The fixed defective scan of ``subject``'s clean crop (a file, mm, head frame) at ``level``: the scan (mm,
    head frame) and a report (level, seed, share of the crop the scanner saw, points)."""
    from ..mesh_io import load_left_pinna  # noqa: PLC0415

    clean = load_left_pinna(crop_path)
    draw = defective_scan(clean, level, np.random.default_rng(subject_seed(subject, seed)), posed=False)
    report = {"crop": str(crop_path), "subject": subject, "level": level, "seed": int(seed),
              "defects": recipe_of(level), "kept_share": round(draw.kept_share, 4),
              "vertices": int(len(draw.mesh.vertices)), "faces": int(len(draw.mesh.faces))}
    return draw.mesh, report
