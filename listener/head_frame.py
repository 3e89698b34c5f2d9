"""The project frame of a head scan in any pose and unit: interaural axis through the two ear-canal entrances,
origin at their middle, +x towards the nose, +y left, +z up, millimetres.

The steps, each on the scan itself (no template head):

1. Units from the head's size (:mod:`listener.units`).
2. The mid-sagittal plane: the plane the surface is most nearly mirror-symmetric about (mirror ICP from each
   principal axis; the best of the three).
3. The two conchae: the side view of each half as a depth map; a grey closing with a 12 mm disk fills the
   cavum conchae, and the deepest fill is the concha. Both must be found, mirror images of each other.
4. The ear-canal entrances: the floor of the canal pit each concha leads into, as the BEM source is placed
   (:func:`mesh2hrtf_io.ear_canal.ear_canal_centre`); the axis through the two is refined until it holds still.
5. Front and up: the nose is the sharpest peak of the mid-sagittal profile, up is where the skull is (the
   centroid of the surface within 130 mm of the interaural centre). The pitch about the interaural axis is set
   so that the nose tip lies at the elevation measured on the SONICOM heads (-6 deg; ``data/head_frame.yaml``).

A head already in the project frame (canal midpoint within 10 mm of the origin, axis within 5 deg of +y, x within
15 deg of the one found) stays exactly as it is.
"""
from __future__ import annotations

import argparse
import json
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import trimesh
import yaml
from scipy import ndimage
from scipy.spatial import cKDTree

from mesh2hrtf_io.ear_canal import ear_canal_centre
from mesh2hrtf_io.errors import Mesh2HrtfIoError

from .errors import ListenerError
from .units import UNIT_MM, infer_unit


def settings() -> dict:
    """The constants of ``listener/data/head_frame.yaml``."""
    text = resources.files("listener").joinpath("data/head_frame.yaml").read_text(encoding="utf-8")
    return yaml.safe_load(text)


@dataclass(frozen=True)
class HeadFrame:
    """Where a head scan's project frame is. ``matrix``: 4x4, from the scan's coordinates (its own unit) to the
    project frame in millimetres (scale included). Points are in the project frame (mm)."""

    matrix: np.ndarray
    unit: str
    kept: bool
    left_canal_mm: np.ndarray
    right_canal_mm: np.ndarray
    nose_tip_mm: np.ndarray
    symmetry_rms_mm: float
    concha_depth_mm: tuple[float, float]
    notes: list[str] = field(default_factory=list)

    def apply(self, mesh: trimesh.Trimesh) -> trimesh.Trimesh:
        """``mesh`` (the scan's coordinates) moved into the project frame (mm); faces and their order unchanged."""
        vertices = np.asarray(mesh.vertices) @ self.matrix[:3, :3].T + self.matrix[:3, 3]
        return trimesh.Trimesh(vertices, np.asarray(mesh.faces), process=False)

    def as_dict(self) -> dict:
        """JSON-ready summary (mm, deg)."""
        rotation = self.matrix[:3, :3] / UNIT_MM[self.unit]
        return {"unit": self.unit, "kept_as_given": self.kept, "matrix": np.round(self.matrix, 9).tolist(),
                "rotation_deg": round(float(np.degrees(np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1, 1)))), 3),
                "left_canal_mm": np.round(self.left_canal_mm, 3).tolist(),
                "right_canal_mm": np.round(self.right_canal_mm, 3).tolist(),
                "nose_tip_mm": np.round(self.nose_tip_mm, 3).tolist(),
                "symmetry_rms_mm": round(self.symmetry_rms_mm, 3),
                "concha_depth_mm": [round(d, 2) for d in self.concha_depth_mm], "notes": list(self.notes)}


def find_head_frame(mesh: trimesh.Trimesh, source: str = "head mesh", config: dict | None = None) -> HeadFrame:
    """The project frame of the head scan ``mesh`` (any pose, mm/cm/m).

    Raises
    ------
    ListenerError
        If the scan is not head-sized or in inches, has no ear (or only one), or its front/up is ambiguous.
    """
    config = config or settings()
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if len(mesh.faces) == 0 or not np.isfinite(vertices).all():
        raise ListenerError(f"{source}: the head mesh is empty or holds NaN/inf vertices; re-export it")
    unit = infer_unit(vertices, tuple(config["units"]["head_diameter_mm"]), source)
    scale = UNIT_MM[unit]
    # merged vertices (an STL repeats them per triangle), so that the canal walk can step between faces
    head = trimesh.Trimesh(vertices * scale, np.asarray(mesh.faces), process=True)
    samples = _surface_samples(head, config["concha"]["samples_per_mm2"])
    normal, offset, rms = symmetry_plane(samples, config["symmetry"])
    seeds, depths = concha_pits(samples, normal, offset, config["concha"], source)
    _check_ear_resolution(head, [side[0] for side in seeds], float(config["concha"]["max_ear_edge_mm"]), source)
    pits = canal_seeds(head, seeds, normal, offset, source)
    side_a, side_b = canal_entrances(head, pits[0], pits[1], config["canal"], source)
    _check_canals(head, (side_a, side_b), pits, normal, offset, config["canal"], source)
    origin = (side_a + side_b) / 2.0
    axis = (side_a - side_b) / np.linalg.norm(side_a - side_b)
    front, up, nose = front_and_up(samples, origin, axis, config["profile"], source)
    elevation = np.radians(config["pitch"]["nose_elevation_deg"])
    x = np.cos(elevation) * front - np.sin(elevation) * up
    z = np.sin(elevation) * front + np.cos(elevation) * up
    y = np.cross(z, x)
    left, right = (side_a, side_b) if y @ axis > 0 else (side_b, side_a)
    rotation = np.vstack([x, y, z])
    matrix = np.eye(4)
    matrix[:3, :3] = rotation * scale
    matrix[:3, 3] = -rotation @ origin
    notes = [f"units: {unit}"]
    kept = unit == "mm" and _near_identity(rotation, origin, config["kept"])
    if kept:
        matrix = np.eye(4)
        notes.append("already in the project frame: kept as given")
    to_frame = matrix[:3, :3] / scale if not kept else np.eye(3)
    shift = matrix[:3, 3]
    return HeadFrame(matrix=matrix, unit=unit, kept=kept, left_canal_mm=to_frame @ left + shift,
                     right_canal_mm=to_frame @ right + shift, nose_tip_mm=to_frame @ nose + shift,
                     symmetry_rms_mm=rms, concha_depth_mm=(float(depths[0]), float(depths[1])), notes=notes)


def _surface_samples(head: trimesh.Trimesh, per_mm2: float) -> np.ndarray:
    """Points on the surface (mm), as many as ``per_mm2`` per square millimetre; the same points (on the same
    faces, at the same barycentric places) for any pose and scale of the same mesh."""
    count = int(min(2_000_000, max(50_000, head.area * per_mm2)))
    points, _ = trimesh.sample.sample_surface(head, count, seed=7)
    return np.asarray(points)


def _mirror_rms(tree: cKDTree, subset: np.ndarray, normal: np.ndarray, offset: float) -> float:
    """RMS distance (mm) of the nearest 90 % of ``subset`` mirrored about ``normal @ p = offset`` to the cloud."""
    distance, _ = tree.query(subset - 2.0 * (subset @ normal - offset)[:, None] * normal)
    return float(np.sqrt(np.mean(np.sort(distance)[: int(0.9 * len(distance))] ** 2)))


def _polish_plane(tree: cKDTree, subset: np.ndarray, normal: np.ndarray, offset: float,
                  ) -> tuple[np.ndarray, float, float]:
    """The plane near ``normal``/``offset`` with the smallest mirror RMS, by Nelder-Mead over two tilts and the
    offset. Mirror ICP creeps: its nearest-point pairs hold the plane where it is, and on P143's head 60 rounds
    stopped 12 deg off (600 reached 2.5 deg); the polish goes on to 0.7 deg."""
    from scipy.optimize import minimize  # noqa: PLC0415

    u = np.cross(normal, np.eye(3)[np.argmin(np.abs(normal))])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)

    def plane(x: np.ndarray) -> tuple[np.ndarray, float]:
        tilted = normal + x[0] * u + x[1] * v
        return tilted / np.linalg.norm(tilted), offset + x[2]

    simplex = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.0, 0.05, 0.0], [0.0, 0.0, 2.0]])  # ~3 deg, 2 mm
    result = minimize(lambda x: _mirror_rms(tree, subset, *plane(x)), np.zeros(3), method="Nelder-Mead",
                      options={"xatol": 1e-4, "fatol": 1e-5, "initial_simplex": simplex})
    polished, moved = plane(result.x)
    return polished, moved, float(result.fun)


def mirror_icp_planes(points: np.ndarray, config: dict) -> tuple[cKDTree, np.ndarray, list[tuple[float, np.ndarray, float]]]:
    """Mirror ICP from each principal axis of ``points`` (mm): pair each point with the surface point nearest its
    mirror image, fit the reflection that maps the points onto their partners (Kabsch with the determinant held at
    -1), take its plane, until it moves less than 0.005 deg. Returns the cloud's tree, the points measured (the
    first ``config["points"]``) and one (mirror RMS in mm, normal, offset) per start."""
    rng = np.random.default_rng(0)
    cloud = points[rng.choice(len(points), min(len(points), 100_000), replace=False)]
    subset = cloud[: int(config["points"])]
    tree = cKDTree(cloud)
    centre = subset.mean(axis=0)
    _, _, axes = np.linalg.svd(subset - centre, full_matrices=False)
    starts = []
    for normal in axes:
        offset = float(normal @ centre)
        for _ in range(int(config["iterations"])):
            distance, index = tree.query(subset - 2.0 * (subset @ normal - offset)[:, None] * normal)
            keep = distance <= np.percentile(distance, 90)
            here, partner = subset[keep], cloud[index[keep]]
            here_mean, partner_mean = here.mean(axis=0), partner.mean(axis=0)
            u, _, vt = np.linalg.svd((here - here_mean).T @ (partner - partner_mean))
            flip = np.diag([1.0, 1.0, -1.0]) if np.linalg.det(vt.T @ u.T) > 0 else np.eye(3)
            reflection = vt.T @ flip @ u.T
            new = np.linalg.eigh((reflection + reflection.T) / 2.0)[1][:, 0]
            new = new if new @ normal > 0 else -new
            offset = float(new @ (partner_mean - reflection @ here_mean)) / 2.0
            moved = np.degrees(np.arccos(np.clip(new @ normal, -1.0, 1.0)))
            normal = new
            if moved < 0.005:
                break
        starts.append((_mirror_rms(tree, subset, normal, offset), normal, offset))
    return tree, subset, starts


def symmetry_plane(points: np.ndarray, config: dict) -> tuple[np.ndarray, float, float]:
    """The plane ``normal @ p = offset`` (mm) the points are most nearly mirror-symmetric about, and the RMS
    distance (mm) of the mirrored points to the surface (the nearest 90 %): the planes of
    :func:`mirror_icp_planes` polished by minimising the RMS directly (:func:`_polish_plane`), the lowest ICP RMS
    first, and the best of them. A start whose ICP RMS is more than ``polish_within`` times the best polished RMS
    is not polished: the polish moves a plane a few degrees, and on the four heads with ears in ../shared/data the
    other two axes' planes lie 2.6-4.9 times above the polished mid-sagittal one after ICP and the polish lowers
    them by at most 6 % (``studies/symmetry_starts.py``). Without ``polish_within`` every start is polished."""
    tree, subset, starts = mirror_icp_planes(points, config)
    within = config.get("polish_within")
    best = None
    for icp_rms, normal, offset in sorted(starts, key=lambda start: start[0]):
        if best is not None and within is not None and icp_rms > float(within) * best[2]:
            continue
        normal, offset, rms = _polish_plane(tree, subset, normal, offset)
        if best is None or rms < best[2]:
            best = (normal, offset, rms)
    return best


def _disk(radius_cells: float) -> np.ndarray:
    r = int(np.ceil(radius_cells))
    grid = np.mgrid[-r:r + 1, -r:r + 1]
    return (grid ** 2).sum(axis=0) <= radius_cells ** 2


def concha_pits(points: np.ndarray, normal: np.ndarray, offset: float, config: dict,
                source: str) -> tuple[list[list[np.ndarray]], list[float]]:
    """Where each concha may lead into its canal (mm; the +normal side first): a few points of the concha's deep
    part (filled by at least ``deep_share`` of the deepest fill), its most medial point first, then the deepest
    fills at least ``seed_spacing_mm`` apart; and the deepest fill of each side (mm).

    Raises
    ------
    ListenerError
        If a side has no concha as deep as ``min_depth_mm``.
    """
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    a_axis = np.cross(normal, helper)
    a_axis /= np.linalg.norm(a_axis)
    b_axis = np.cross(normal, a_axis)
    cell = float(config["cell_mm"])
    a, b = points @ a_axis, points @ b_axis
    ia = np.floor((a - a.min()) / cell).astype(int)
    ib = np.floor((b - b.min()) / cell).astype(int)
    shape = (ia.max() + 1, ib.max() + 1)
    radius = float(config["closing_radius_mm"]) / cell
    seeds, depths = [], []
    for side in (1.0, -1.0):
        lateral = side * (points @ normal - offset)
        depth = np.full(shape, -np.inf)
        np.maximum.at(depth, (ia, ib), lateral)
        gaps = ~np.isfinite(depth)
        depth = np.where(gaps, ndimage.maximum_filter(np.where(gaps, -1e9, depth), size=3), depth)
        valid = depth > -1e8
        floor = depth[valid].min() - 50.0
        filled = np.where(valid, depth, floor)
        closed = ndimage.grey_closing(filled, footprint=_disk(radius))
        pit = np.where(ndimage.binary_erosion(valid, structure=_disk(radius + 3.0 / cell)), closed - filled, 0.0)
        pit = np.where(valid & (depth >= float(config["min_lateral_mm"])), pit, 0.0)
        i, j = np.unravel_index(int(np.argmax(pit)), pit.shape)
        depths.append(float(pit[i, j]))
        # the deepest fill may be the cymba or a fossa: the canal pit is looked for under several points of the
        # deep part, the most medial one first
        deep = pit >= float(config["deep_share"]) * pit[i, j]
        cells = [np.unravel_index(int(np.argmin(np.where(deep, depth, np.inf))), pit.shape)]
        spacing = float(config["seed_spacing_mm"]) / cell
        remaining = np.where(deep, pit, 0.0)
        grid = np.indices(shape)
        while len(cells) < int(config["seeds"]) and remaining.max() > 0:
            k = np.unravel_index(int(np.argmax(remaining)), shape)
            cells.append(k)
            remaining[np.hypot(grid[0] - k[0], grid[1] - k[1]) < spacing] = 0.0
        seeds.append([(a.min() + (k[0] + 0.5) * cell) * a_axis + (b.min() + (k[1] + 0.5) * cell) * b_axis
                      + (offset + side * depth[k]) * normal for k in cells])
    minimum = float(config["min_depth_mm"])
    missing = [d for d in depths if d < minimum]
    if len(missing) == 2:
        raise ListenerError(f"{source}: no ears found (the deepest pits on the two sides are {depths[0]:.1f} and "
                            f"{depths[1]:.1f} mm deep, a concha at least {minimum:g} mm): a head scan with both "
                            "pinnae is needed")
    if missing:
        raise ListenerError(f"{source}: only one ear found (the deepest pit on the other side is "
                            f"{min(depths):.1f} mm deep, a concha at least {minimum:g} mm): a head scan with both "
                            "pinnae is needed")
    return seeds, depths


#: Canal floors found from different seeds of one concha that lie this close (mm) are the same pit.
CANAL_AGREE_MM = 3.0


def canal_seeds(head: trimesh.Trimesh, seeds: list[list[np.ndarray]], normal: np.ndarray, offset: float,
                source: str) -> list[np.ndarray]:
    """Per side, the canal floor (mm) most of the seeds lead to: from each seed's foot on the mid-sagittal plane a
    ray along the side's normal leaves the head in the concha and leads down into a pit; the pits within
    ``CANAL_AGREE_MM`` of each other are one, and the canal is the most medial pit of the largest group (ties:
    the most medial). A seed at the concha's back rim can lead behind the pinna, into the fold against the
    head, which lies more medial than the canal (P143's right ear: 2.3 mm, 17 mm behind it).

    Raises
    ------
    ListenerError
        If no seed of a side leads into a pit.
    """
    found = []
    for side, candidates in zip((1.0, -1.0), seeds):
        floors = []
        for seed in candidates:
            foot = seed - (seed @ normal - offset) * normal
            rotation = _ear_frame(foot, side * normal)
            local = trimesh.Trimesh((np.asarray(head.vertices) - foot) @ rotation.T, head.faces, process=False)
            try:
                floors.append(ear_canal_centre(local, "left", source, require_floor=True) @ rotation + foot)
            except Mesh2HrtfIoError:
                continue
        if not floors:
            raise ListenerError(f"{source}: no ear canal found in the concha on one side (no canal pit under "
                                f"{len(candidates)} points of its deepest part); is the canal blocked flat or "
                                "the ear damaged in the scan?")
        groups = [[other for other in floors if np.linalg.norm(other - floor) <= CANAL_AGREE_MM] for floor in floors]
        medial = [min(abs(point @ normal - offset) for point in group) for group in groups]
        best = min(range(len(groups)), key=lambda i: (-len(groups[i]), medial[i]))
        found.append(min(groups[best], key=lambda point: abs(point @ normal - offset)))
    return found


def _ear_frame(origin: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """A rotation (rows x, y, z) with y along ``axis``; x and z arbitrary."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    z = np.cross(helper, axis)
    z /= np.linalg.norm(z)
    return np.vstack([np.cross(axis, z), axis, z])


def canal_entrances(head: trimesh.Trimesh, pit_a: np.ndarray, pit_b: np.ndarray, config: dict,
                    source: str) -> tuple[np.ndarray, np.ndarray]:
    """The ear-canal entrances (mm, scan orientation) the conchae at ``pit_a`` and ``pit_b`` lead into: the axis
    through the two is moved onto their canal floors until it holds still."""
    a, b = np.asarray(pit_a, float), np.asarray(pit_b, float)
    for _ in range(int(config["iterations"])):
        origin = (a + b) / 2.0
        axis = (a - b) / np.linalg.norm(a - b)
        rotation = _ear_frame(origin, axis)
        local = trimesh.Trimesh((np.asarray(head.vertices) - origin) @ rotation.T, head.faces, process=False)
        try:
            new_a = ear_canal_centre(local, "left", source, require_floor=True) @ rotation + origin
            new_b = ear_canal_centre(local, "right", source, require_floor=True) @ rotation + origin
        except Mesh2HrtfIoError as error:
            raise ListenerError(f"{source}: no ear canal found at the conchae ({error})") from error
        moved = max(np.linalg.norm(new_a - a), np.linalg.norm(new_b - b))
        a, b = new_a, new_b
        if moved < float(config["tolerance_mm"]):
            break
    return a, b


def _ear_edge_mm(head: trimesh.Trimesh, point: np.ndarray) -> float:
    """The median edge (mm, from the faces' areas as if equilateral) within 20 mm of ``point``; inf if none."""
    near = np.linalg.norm(head.triangles_center - point, axis=1) < 20.0
    return float(np.sqrt(np.median(head.area_faces[near]) * 4.0 / np.sqrt(3.0))) if near.any() else np.inf


def _check_ear_resolution(head: trimesh.Trimesh, pits: list[np.ndarray], max_edge_mm: float, source: str) -> None:
    """Refuse a scan whose ears are meshed coarser than ``max_edge_mm`` (the median edge within 20 mm of each
    concha): neither the canal nor the pinna's shape can be found on it."""
    for pit in pits:
        edge = _ear_edge_mm(head, pit)
        if edge > max_edge_mm:
            raise ListenerError(f"{source}: the ear at {np.round(pit, 1).tolist()} is meshed with {edge:.1f} mm edges; "
                                f"a pinna needs at most {max_edge_mm:g} mm (scan or export the head finer at the ears)")


def _check_canals(head: trimesh.Trimesh, canals: tuple[np.ndarray, np.ndarray], pits: list[np.ndarray],
                  normal: np.ndarray, offset: float, config: dict, source: str) -> None:
    """Refuse ear canals that do not lie in their conchae (deeper than the concha's deepest point seen from the
    side, and near it) or that are far from mirror images of each other about the mid-sagittal plane (heads are
    not symmetric: SONICOM's canals lie 0.1-5 mm apart in depth and up to 11 mm along the head)."""
    def depth(point: np.ndarray) -> float:
        return abs(float(point @ normal) - offset)

    problems = []
    for name, canal, pit in zip(("first", "second"), canals, pits):
        if depth(canal) > depth(pit) + 3.0 or np.linalg.norm(canal - pit) > float(config["max_from_concha_mm"]):
            problems.append(f"the {name} ear canal ({depth(canal):.1f} mm from the mid-sagittal plane) lies outside "
                            f"its concha ({depth(pit):.1f} mm, {np.linalg.norm(canal - pit):.1f} mm away)")
    lateral = abs(depth(canals[0]) - depth(canals[1]))
    if lateral > float(config["max_mirror_mm"]):
        problems.append(f"the two ear canals are {lateral:.1f} mm apart in depth (at most {config['max_mirror_mm']:g})")
    along = float(np.linalg.norm((canals[0] - (canals[0] @ normal) * normal) - (canals[1] - (canals[1] @ normal) * normal)))
    if along > float(config["max_mirror_along_mm"]):
        problems.append(f"the two ear canals are {along:.1f} mm apart along the head (at most "
                        f"{config['max_mirror_along_mm']:g})")
    if problems:
        raise ListenerError(f"{source}: " + "; ".join(problems) + f": the ears are not resolved well enough (edges "
                            f"about {_ear_edge_mm(head, canals[0]):.1f} mm at the ear; a scan needs 1-2 mm there)")


def sagittal_profile(points: np.ndarray, origin: np.ndarray, axis: np.ndarray, config: dict,
                     across_mm: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The outline of a sagittal section around the interaural axis, ``across_mm`` along the axis from the
    interaural centre: angles (deg, bin centres), the largest distance (mm) from the axis in each bin (NaN where
    empty), the point there (NaN where empty), and the in-plane basis (2 x 3: angle 0 and angle 90 deg)."""
    rotation = _ear_frame(origin, axis)
    local = (points - origin) @ rotation.T
    near = np.abs(local[:, 1] - across_mm) < float(config["half_width_mm"])
    x, z = local[near, 0], local[near, 2]
    step = float(config["bin_deg"])
    count = int(round(360.0 / step))
    bins = np.floor((np.degrees(np.arctan2(z, x)) % 360.0) / step).astype(int) % count
    radius = np.hypot(x, z)
    outline = np.full(count, np.nan)
    where = np.full(count, -1)
    order = np.argsort(radius)
    outline[bins[order]] = radius[order]
    where[bins[order]] = np.flatnonzero(near)[order]
    tips = np.full((count, 3), np.nan)
    tips[where >= 0] = points[where[where >= 0]]
    return (np.arange(count) + 0.5) * step, outline, tips, rotation[[0, 2]]


def _sector_mean(outline: np.ndarray, centre: int, half: int) -> float:
    values = outline[[(centre + j) % len(outline) for j in range(-half, half + 1)]]
    return float(np.nanmean(values)) if np.isfinite(values).any() else np.nan


def front_and_up(points: np.ndarray, origin: np.ndarray, axis: np.ndarray, config: dict,
                 source: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors (scan orientation) from the interaural centre to the nose tip and up, both normal to the
    axis, and the nose tip (mm).

    The nose tip is the peak of the mid-sagittal outline that falls most on every side: along the outline
    (``window_deg`` either way) and across it (the outlines ``nose_across_mm`` either side of the mid-sagittal
    plane, at the same angle, where the cheeks are); a neck's cut edge or a chin falls far less across. Up is
    the side of the nose where the outline lies farther from the axis (the skull's dome against the neck:
    the mean over the 90 deg sector centred a right angle from the nose).

    Raises
    ------
    ListenerError
        If no nose stands out of the profile, or up is ambiguous.
    """
    centres, outline, tips, basis = sagittal_profile(points, origin, axis, config)
    across = float(config["nose_across_mm"])
    beside = [sagittal_profile(points, origin, axis, config, offset)[1] for offset in (-across, across)]
    step = float(config["bin_deg"])
    inner, outer = (int(round(w / step)) for w in config["window_deg"])
    low, high = config["nose_distance_mm"]
    count = len(outline)
    score = np.full(count, -np.inf)
    for k in range(count):
        if not low <= outline[k] <= high:
            continue
        before = outline[[(k - j) % count for j in range(inner, outer + 1)]]
        after = outline[[(k + j) % count for j in range(inner, outer + 1)]]
        if np.isnan(before).all() or np.isnan(after).all():
            continue
        side_drop = min(outline[k] - (side[k] if np.isfinite(side[k]) else 0.0) for side in beside)
        score[k] = min(outline[k] - max(np.nanmin(before), np.nanmin(after)), side_drop)
    k = int(np.argmax(score))
    if not np.isfinite(score[k]) or score[k] < float(config["nose_min_mm"]):
        raise ListenerError(f"{source}: no nose stands out of the head's mid-sagittal outline (the sharpest peak "
                            f"falls {score[k]:.1f} mm, a nose at least {config['nose_min_mm']:g}): front is "
                            "ambiguous; is this a whole head with its face?")
    angle = np.radians(centres[k])
    front = np.cos(angle) * basis[0] + np.sin(angle) * basis[1]
    quarter = int(round(90.0 / step))
    dome = _sector_mean(outline, k + quarter, quarter // 2) - _sector_mean(outline, k - quarter, quarter // 2)
    if not np.isfinite(dome):
        raise ListenerError(f"{source}: the head's mid-sagittal outline is missing a right angle from the nose: up "
                            "is ambiguous; is this a whole head (skull above the ears, neck below)?")
    if abs(dome) < float(config["up_min_contrast_mm"]):
        raise ListenerError(f"{source}: the head's outline lies as far from the interaural axis on both sides of "
                            f"the nose ({dome:+.1f} mm): up is ambiguous; is this a whole head (skull above the "
                            "ears, neck below)?")
    side_at = -np.sin(angle) * basis[0] + np.cos(angle) * basis[1]
    up = side_at if dome > 0 else -side_at
    return front, up, tips[k]


def _near_identity(rotation: np.ndarray, origin: np.ndarray, limits: dict) -> bool:
    """Whether the frame found is within ``limits`` of the scan's own (origin mm, axis and pitch deg)."""
    axis_deg = np.degrees(np.arccos(np.clip(rotation[1, 1], -1, 1)))
    pitch_deg = np.degrees(np.arccos(np.clip(rotation[0, 0], -1, 1)))
    return bool(np.linalg.norm(origin) <= limits["origin_mm"] and axis_deg <= limits["axis_deg"]
                and pitch_deg <= limits["pitch_deg"])


def survey(root: Path) -> list[dict]:
    """The frame found on each head of a data root (SONICOM subjects with both ears from their two graded files,
    ``heads/*.ply``), with the scan's own frame's offsets from it: the constants of ``data/head_frame.yaml``
    come from here."""
    from .dataset_heads import both_ears_head  # noqa: PLC0415

    heads = [(f"sonicom/{path.name} (both ears)", lambda path=path: both_ears_head(path))
             for path in sorted(root.glob("sonicom/*")) if (path / "head_graded_right.ply").is_file()]
    heads += [(str(path.relative_to(root)), lambda path=path: trimesh.load(path, process=False, force="mesh"))
              for path in sorted(root.glob("heads/*.ply"))]
    config = settings()
    config["kept"] = {"origin_mm": -1.0, "axis_deg": 0.0, "pitch_deg": 0.0}
    rows = []
    for name, load in heads:
        try:
            frame = find_head_frame(load(), name, config)
        except ListenerError as error:
            rows.append({"head": name, "refused": str(error)})
            continue
        rotation, shift = frame.matrix[:3, :3], frame.matrix[:3, 3]
        origin = -rotation.T @ shift
        nose = rotation.T @ (frame.nose_tip_mm - shift)
        rows.append({"head": name, "origin_offset_mm": np.round(origin, 2).tolist(),
                     "axis_deg": round(float(np.degrees(np.arccos(np.clip(rotation[1, 1], -1, 1)))), 2),
                     "pitch_deg": round(float(np.degrees(np.arctan2(rotation[0, 2], rotation[0, 0]))), 2),
                     "nose_elevation_deg": round(float(np.degrees(np.arctan2(nose[2] - origin[2], nose[0] - origin[0]))), 2),
                     "symmetry_rms_mm": round(frame.symmetry_rms_mm, 2),
                     "concha_depth_mm": [round(d, 1) for d in frame.concha_depth_mm]})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description="Find the project frame of head scans.")
    parser.add_argument("--survey", type=Path, help="a data root: the frame found on each of its heads")
    args = parser.parse_args()
    if args.survey:
        for row in survey(args.survey):
            print(json.dumps(row))


if __name__ == "__main__":
    main()
