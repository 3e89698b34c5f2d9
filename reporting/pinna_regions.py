"""Where a condition's pinna departs from the scan: scan -> model distances per anatomical region.

Every scan point gets the region (``ppm/data/landmark_regions.yaml``) of the landmark nearest to it, the
landmarks taken on the subject's aligned PPM (template vertex ids, so they sit on this subject's ear). Points
farther than ``reach_mm`` from every landmark (the head around the ear) form the region "surroundings".
Millimetres, project frame (x front, y left, z up).
"""
from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

OUTSIDE = "surroundings"


def landmark_regions() -> dict[str, list[str]]:
    """Region name -> its landmark names, in the data file's order."""
    text = resources.files("ppm").joinpath("data/landmark_regions.yaml").read_text(encoding="utf-8")
    return {str(region): list(names) for region, names in yaml.safe_load(text).items()}


def landmark_positions_mm(pinna_path: str | os.PathLike, landmarks_path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Landmark name -> position (mm) on a pinna mesh of the template's topology (the aligned PPM)."""
    import trimesh  # noqa: PLC0415

    from ppm.landmarks import read_landmark_file  # noqa: PLC0415

    pinna = trimesh.load(pinna_path, process=False, force="mesh")
    entries = read_landmark_file(landmarks_path)
    positions = {}
    for name, entry in entries.items():
        vertex = int(entry["vertex"])
        if not 0 <= vertex < len(pinna.vertices):
            raise ValueError(f"{landmarks_path}: landmark {name!r} is vertex {vertex}, but {pinna_path} has "
                             f"{len(pinna.vertices)} vertices; give the aligned PPM of the same template")
        positions[name] = np.asarray(pinna.vertices[vertex], np.float64)
    return positions


def label_points(points_mm: np.ndarray, positions_mm: dict[str, np.ndarray], reach_mm: float = 8.0) -> np.ndarray:
    """Region of each point (n,) as strings: that of its nearest landmark, or "surroundings" beyond `reach_mm`."""
    from scipy.spatial import cKDTree  # noqa: PLC0415

    regions = landmark_regions()
    names, owners = [], []
    for region, landmarks in regions.items():
        missing = [n for n in landmarks if n not in positions_mm]
        if missing:
            raise ValueError(f"landmarks {missing} of region {region!r} are not in the template's landmarks.yaml")
        names += landmarks
        owners += [region] * len(landmarks)
    distance, nearest = cKDTree(np.array([positions_mm[n] for n in names])).query(np.asarray(points_mm, np.float64))
    labels = np.array(owners, dtype=object)[nearest]
    labels[distance > reach_mm] = OUTSIDE
    return labels


def region_table(labels: np.ndarray, distances_mm: np.ndarray, over_mm: float = 1.0) -> list[dict]:
    """Per region (data-file order, then surroundings): scan points, median and 95th percentile of their distance
    (mm) and the share (%) farther than `over_mm`."""
    rows = []
    for region in [*landmark_regions(), OUTSIDE]:
        values = np.asarray(distances_mm)[labels == region]
        if len(values) == 0:
            continue
        rows.append({"region": region, "points": int(len(values)), "median_mm": float(np.median(values)),
                     "p95_mm": float(np.percentile(values, 95)),
                     "over_1mm_percent": float(100.0 * np.mean(values > over_mm))})
    return rows


def subject_regions(results: str | os.PathLike, subject: str, conditions: list[str],
                    positions_mm: dict[str, np.ndarray]) -> dict[str, list[dict]]:
    """Condition -> region table of one subject, from the evaluation's per-point distances
    (``results/<subject>/evaluation/<condition>/distances.npz``) and the landmark positions (mm) on its aligned
    PPM (:func:`landmark_positions_mm`, or those kept with its head: :mod:`reporting.kept_fit`)."""
    results = Path(results)
    tables = {}
    for condition in conditions:
        if condition == "reference":
            continue
        data = np.load(results / subject / "evaluation" / condition / "distances.npz")
        labels = label_points(data["target_points_mm"], positions_mm)
        tables[condition] = region_table(labels, data["target_to_model"])
    return tables


def worst_regions(table: list[dict], count: int = 2) -> list[dict]:
    """The `count` pinna regions (not the surroundings) with the largest median distance."""
    pinna = [row for row in table if row["region"] != OUTSIDE]
    return sorted(pinna, key=lambda row: row["median_mm"], reverse=True)[:count]
