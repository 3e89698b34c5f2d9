"""Anatomical landmarks of a template: named vertex ids on the common topology.

A template folder holds `landmarks.yaml`: per landmark a `vertex` id and the `position_mm` it was
picked at (mm, project frame), plus a one-line description. Bones and shape-key regions refer to
landmarks by name (`ppm/data/rig.yaml`), never by raw coordinates. Templates that share a
topology (leave-one-subject-out builds) share the vertex ids.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from scipy.spatial import cKDTree

from core.atomic import write_text_atomic
from .errors import PpmError

LANDMARKS_NAME = "landmarks.yaml"


def _landmark_file(template) -> Path:
    folder = template.folder if hasattr(template, "folder") else Path(template)
    if folder is None:
        raise PpmError("this template was not loaded from a folder, so it has no landmarks.yaml")
    return Path(folder) / LANDMARKS_NAME


def read_landmark_file(path: str | Path) -> dict[str, dict]:
    """The raw entries of a landmarks.yaml: name -> {vertex, position_mm, description}."""
    path = Path(path)
    if not path.is_file():
        raise PpmError(f"{path}: missing landmarks file; every template folder needs one (see `ppm snap-landmarks`)")
    entries = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    if not isinstance(entries, dict) or not entries:
        raise PpmError(f"{path}: expected a mapping of landmark name -> {{vertex, position_mm}}")
    return entries


def load_landmarks(template) -> dict[str, int]:
    """Landmark name -> vertex id for a `Template` (or a template folder).

    Raises
    ------
    PpmError
        If the file is missing, a landmark has no vertex id, or an id is outside the mesh.
    """
    path = _landmark_file(template)
    entries = read_landmark_file(path)
    n = len(template.vertices_mm) if hasattr(template, "vertices_mm") else None
    ids = {}
    for name, entry in entries.items():
        vertex = entry.get("vertex") if isinstance(entry, dict) else None
        if vertex is None:
            raise PpmError(f"{path}: landmark {name!r} has no vertex id; run `ppm snap-landmarks {path.parent}`")
        if n is not None and not 0 <= int(vertex) < n:
            raise PpmError(f"{path}: landmark {name!r} vertex {vertex} is outside the template's {n} vertices")
        ids[name] = int(vertex)
    return ids


def snap_landmarks(path: str | Path, vertices_mm: np.ndarray) -> dict[str, int]:
    """Set every landmark's `vertex` to the template vertex nearest its `position_mm`; rewrite the file.

    Returns the name -> vertex id mapping. The snapping distance is logged in the file.
    """
    path = Path(path)
    entries = read_landmark_file(path)
    tree = cKDTree(np.asarray(vertices_mm, np.float64))
    ids = {}
    for name, entry in entries.items():
        position = np.asarray(entry["position_mm"], dtype=np.float64)
        distance, vertex = tree.query(position)
        entry["vertex"] = int(vertex)
        entry["snap_distance_mm"] = round(float(distance), 3)
        ids[name] = int(vertex)
    header = ("# Anatomical landmarks of this template (mm, +x front, +y left, +z up).\n"
              "# position_mm: where a person picked the landmark on renders of the template;\n"
              "# vertex: the nearest template vertex (written by `ppm snap-landmarks`).\n")
    write_text_atomic(path, header + yaml.safe_dump(entries, sort_keys=False, default_flow_style=None))
    return ids
