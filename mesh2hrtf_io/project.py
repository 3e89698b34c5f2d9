"""Writing a Mesh2HRTF 1.2.4 project (NumCalc input) from a head mesh in millimetres.

Layout (see ../shared/docs/mesh2hrtf_project_format.md): `ObjectMeshes/Reference/{Nodes,Elements}.txt`
in metres, `EvaluationGrids/<grid>/{Nodes,Elements}.txt`, one `NumCalc/source_N/NC.inp` per ear
(source_1 = left ear, source_2 = right ear for "Both ears"), and `parameters.json` for Output2HRTF.
Files use single spaces and LF line endings. Element IDs 0..M-1 follow the mesh's face order with
the ear elements moved to the end (left ear, then right ear), so each ear is one contiguous range.
The project folder is built as `<name>.partial/` and renamed when complete.
"""
from __future__ import annotations

import dataclasses
import json
import logging
import os
from pathlib import Path

import numpy as np
import trimesh

from core.atomic import atomic_directory

from .checks import SLIVER_ANGLE_DEG, check_mesh, sliver_count
from .clusters import planned_cluster_tree
from .constants import (DENSITY_KG_M3, EAR_VELOCITY_M_S, GRID_START_ID, MESH2HRTF_VERSION, SOURCE_TO_ROOT,
                        SPEED_OF_SOUND_M_S)
from .errors import Mesh2HrtfIoError
from .frequency_sets import check_frequency_set, is_linear_grid
from .grids import EvaluationGrid
from .units import mm_to_m

log = logging.getLogger(__name__)

SOURCE_TYPES = {"Both ears": ("left", "right"), "Left ear": ("left",), "Right ear": ("right",)}


@dataclasses.dataclass(frozen=True)
class ProjectLayout:
    """What was written: element-ID ranges of the ears, node/element totals and the source folders."""

    ear_ranges: dict[str, tuple[int, int]]
    n_object_nodes: int
    n_object_elements: int
    n_nodes: int
    n_elements: int
    sources: tuple[str, ...]
    frequencies_hz: tuple[float, ...]


def _nodes_text(ids: np.ndarray, points_m: np.ndarray) -> str:
    lines = [str(len(ids))]
    lines += [f"{i} {x:.6f} {y:.6f} {z:.6f}" for i, (x, y, z) in zip(ids, points_m)]
    return "\n".join(lines) + "\n"


def _elements_text(ids: np.ndarray, nodes: np.ndarray, prop: int, group: int) -> str:
    lines = [str(len(ids))]
    lines += [f"{i} {a} {b} {c} {prop} 0 {group}" for i, (a, b, c) in zip(ids, nodes)]
    return "\n".join(lines) + "\n"


def _check_frequencies(frequencies_hz) -> np.ndarray:
    f = check_frequency_set(frequencies_hz, "frequencies_hz")
    if f.max() >= 1e6:
        raise Mesh2HrtfIoError(f"frequencies_hz reach {f.max():g} Hz; NC.inp writes at most 99999.99 Hz")
    return f


MAIN_PARAMETERS_II = "## 2. Main Parameters II"


def main_parameters_ii(cluster_size_m: float) -> str:
    """NC.inp's Main Parameters II line: the level-0 cluster size of the multilevel FMM (m; 0 = NumCalc's own)."""
    return f"0 0 0 {cluster_size_m:.4e} 0 0 0"


def nc_inp_text(title: str, frequencies_hz: np.ndarray, n_elements: int, n_nodes: int, mesh_paths: list[str],
                ear_range: tuple[int, int], ear_label: str, speed_of_sound_m_s: float, density_kg_m3: float,
                method: int = 4, cluster_size_m: float = 0.0) -> str:
    """The NC.inp of one reciprocal ear source (Mesh2HRTF 1.2.4 layout); ``cluster_size_m`` is the level-0
    cluster size of the multilevel FMM (Main Parameters II, 4th value; 0 = NumCalc derives it)."""
    lines = ["##-------------------------------------------", "## NumCalc input written by ppm-hrtf (mesh2hrtf_io)",
             "##-------------------------------------------", f"Mesh2HRTF {MESH2HRTF_VERSION}", "##", title, "##",
             "## Controlparameter I", "0 0 0 0 7 0", "##", "## Controlparameter II",
             f"1 {len(frequencies_hz)} 0.000001 0.00e+00 1 0 0", "##", "## Load Frequency Curve",
             f"0 {len(frequencies_hz) + 1}", "0.000000 0.000000e+00 0.0"]
    lines += [f"{(i + 1) * 1e-6:.6f} {f / 1e4:.6f}e+04 0.0" for i, f in enumerate(frequencies_hz)]
    lines += ["##", "## 1. Main Parameters I", f"2 {n_elements} {n_nodes} 0 0 2 1 {method} 0",
              "##", MAIN_PARAMETERS_II, main_parameters_ii(cluster_size_m),
              "##", "## 3. Main Parameters III", "0 0 0 0",
              "##", "## 4. Main Parameters IV",
              f"{speed_of_sound_m_s:g} {density_kg_m3:.4e} 1.0 0.0e+00 0.0 e+00 0.0e+00 0.0e+00", "##", "NODES"]
    lines += [f"{SOURCE_TO_ROOT}/{p}/Nodes.txt" for p in mesh_paths]
    lines += ["##", "ELEMENTS"]
    lines += [f"{SOURCE_TO_ROOT}/{p}/Elements.txt" for p in mesh_paths]
    lines += ["##", "# SYMMETRY", "# 0 0 0", "# 0.0000e+00 0.0000e+00 0.0000e+00", "##", "BOUNDARY",
              f"## {ear_label}", f"ELEM {ear_range[0]} TO {ear_range[1]} VELO {EAR_VELOCITY_M_S} -1 0.0 -1", "RETU",
              "##", "POST PROCESS", "##", "END"]
    return "\n".join(lines) + "\n"


def write_project(folder: str | os.PathLike, vertices_mm: np.ndarray, faces: np.ndarray,
                  ear_elements: dict[str, np.ndarray], grids: list[EvaluationGrid], frequencies_hz,
                  *, source_type: str = "Both ears", title: str = "ppm-hrtf head",
                  speed_of_sound_m_s: float = SPEED_OF_SOUND_M_S, density_kg_m3: float = DENSITY_KG_M3,
                  reference: bool = True, compute_hrirs: bool = False,
                  numcalc_cluster_size: float | str = "auto") -> ProjectLayout:
    """Validate a head mesh and write a complete Mesh2HRTF 1.2.4 project folder.

    Parameters
    ----------
    folder : path-like
        Project folder to create (replaced only once the new one is complete).
    vertices_mm : (n, 3) float
        Head mesh vertices in millimetres, +x front, +y left, +z up, origin at the interaural centre.
    faces : (m, 3) int
        Triangles, counter-clockwise seen from outside (outward normals).
    ear_elements : dict
        'left' and/or 'right' -> indices into `faces` of the ear-canal element(s) that vibrate.
    grids : list of EvaluationGrid
        Evaluation grids (metres); written in name order, as Output2HRTF lists them.
    frequencies_hz : sequence of float
        Strictly increasing frequencies above 0 Hz.
    source_type : {'Both ears', 'Left ear', 'Right ear'}
        Which ears become reciprocal sources.
    numcalc_cluster_size : 'auto' or float
        Level-0 cluster size of NumCalc's multilevel FMM in metres (0: NumCalc's default); 'auto' chooses
        it from the mesh (:func:`mesh2hrtf_io.clusters.chosen_cluster_size_m`). The tree NumCalc will build
        is written to ``numcalc_clusters.json``.

    Raises
    ------
    Mesh2HrtfIoError
        For an unusable mesh (open, non-manifold, inward normals, metres), missing or overlapping
        ear elements, bad grids or frequencies. Nothing is written then.
    """
    if source_type not in SOURCE_TYPES:
        raise Mesh2HrtfIoError(f"source_type must be one of {sorted(SOURCE_TYPES)}, got {source_type!r}")
    vertices_mm = np.asarray(vertices_mm, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    check_mesh(vertices_mm, faces, source=f"head mesh for {folder}")
    slivers = sliver_count(vertices_mm, faces)
    if slivers:
        log.warning("head mesh for %s has %d sliver triangles (an angle under %g deg): NumCalc's surface pressure can "
                    "spike on them; remesh it (the stitching stage's remove_slivers does)", folder, slivers,
                    SLIVER_ANGLE_DEG)
    frequencies = _check_frequencies(frequencies_hz)
    ears = SOURCE_TYPES[source_type]
    chosen = {}
    for ear in ears:
        ids = np.unique(np.asarray(ear_elements.get(ear, []), dtype=np.int64))
        if len(ids) == 0:
            raise Mesh2HrtfIoError(f"source_type {source_type!r} needs {ear} ear elements; none were given "
                                   "(mark the ear-canal entrance faces)")
        if ids.min() < 0 or ids.max() >= len(faces):
            raise Mesh2HrtfIoError(f"{ear} ear element ids must lie in 0..{len(faces) - 1}")
        chosen[ear] = ids
    if len(chosen) == 2 and np.intersect1d(chosen["left"], chosen["right"]).size:
        raise Mesh2HrtfIoError("the same element is marked as left and right ear")
    names = [g.name for g in grids]
    if not grids or len(set(names)) != len(names):
        raise Mesh2HrtfIoError(f"give at least one evaluation grid, with unique names; got {names}")

    # element order: skin first (original order), then each ear as one contiguous range
    ear_all = np.concatenate([chosen[e] for e in ears])
    skin = np.setdiff1d(np.arange(len(faces)), ear_all)
    order = np.concatenate([skin] + [chosen[e] for e in ears])
    ear_ranges, start = {}, len(skin)
    for ear in ears:
        ear_ranges[ear] = (start, start + len(chosen[ear]) - 1)
        start += len(chosen[ear])

    mesh = trimesh.Trimesh(vertices_mm, faces, process=False)
    tree = planned_cluster_tree(mm_to_m(vertices_mm), faces, numcalc_cluster_size, source=f"head mesh for {folder}")
    grids = sorted(grids, key=lambda g: g.name)
    grid_start = GRID_START_ID if GRID_START_ID > len(vertices_mm) else int(np.ceil((len(vertices_mm) + 1) / 1e5) * 1e5)
    n_nodes = len(vertices_mm) + sum(len(g.points_m) for g in grids)
    n_elements = len(faces) + sum(len(g.faces) for g in grids)
    mesh_paths = ["ObjectMeshes/Reference"] + [f"EvaluationGrids/{g.name}" for g in grids]
    sources = tuple(f"source_{i + 1}" for i in range(len(ears)))
    labels = {"left": "Left ear", "right": "Right ear"}

    with atomic_directory(folder) as tmp:
        reference_dir = tmp / "ObjectMeshes" / "Reference"
        reference_dir.mkdir(parents=True)
        (reference_dir / "Nodes.txt").write_text(_nodes_text(np.arange(len(vertices_mm)), mm_to_m(vertices_mm)),
                                                 newline="\n")
        (reference_dir / "Elements.txt").write_text(
            _elements_text(np.arange(len(faces)), faces[order], prop=0, group=0), newline="\n")
        next_id = grid_start
        for grid in grids:
            grid_dir = tmp / "EvaluationGrids" / grid.name
            grid_dir.mkdir(parents=True)
            node_ids = next_id + np.arange(len(grid.points_m))
            element_ids = next_id + np.arange(len(grid.faces))
            (grid_dir / "Nodes.txt").write_text(_nodes_text(node_ids, grid.points_m), newline="\n")
            (grid_dir / "Elements.txt").write_text(_elements_text(element_ids, node_ids[grid.faces], prop=2, group=1),
                                                   newline="\n")
            next_id += int(np.ceil((max(len(grid.points_m), len(grid.faces)) + 1) / 1e5) * 1e5)
        centres, areas = [], []
        for ear, source in zip(ears, sources):
            source_dir = tmp / "NumCalc" / source
            source_dir.mkdir(parents=True)
            (source_dir / "NC.inp").write_text(
                nc_inp_text(title, frequencies, n_elements, n_nodes, mesh_paths, ear_ranges[ear], labels[ear],
                            speed_of_sound_m_s, density_kg_m3, cluster_size_m=tree.written_m), newline="\n")
            ear_vertices = vertices_mm[np.unique(faces[chosen[ear]])]
            centres.append(mm_to_m((ear_vertices.min(axis=0) + ear_vertices.max(axis=0)) / 2).tolist())
            areas.append(float(mesh.area_faces[chosen[ear]].sum() / 1e6))
        step = float(frequencies[0]) if is_linear_grid(frequencies) or len(frequencies) == 1 else 0.0
        parameters = {
            "projectTitle": title, "Mesh2HRTF_Version": MESH2HRTF_VERSION, "BEM_Type": "ML-FMM BEM",
            "sourceType": source_type, "numSources": len(ears),
            "sourceCenter": centres if len(ears) == 2 else centres[0], "sourceArea": areas,
            "speedOfSound": speed_of_sound_m_s, "densityOfMedium": density_kg_m3,
            "frequencies": frequencies.tolist(), "numFrequencies": len(frequencies),
            "frequencyStepSize": step, "minFrequency": float(frequencies[0]), "maxFrequency": float(frequencies[-1]),
            "evaluationGrids": [g.name for g in grids], "reference": reference, "computeHRIRs": compute_hrirs,
            "3D_SceneUnit": "mm", "exportPictures": False, "materialSearchPaths": [],
            "materials": {labels[e]: {"is_used": True, "index_start": ear_ranges[e][0], "index_end": ear_ranges[e][1]}
                          for e in ears},
        }
        (tmp / "parameters.json").write_text(json.dumps(parameters, indent=4) + "\n", newline="\n")
        (tmp / "numcalc_clusters.json").write_text(json.dumps(tree.as_dict(), indent=2) + "\n", newline="\n")
    return ProjectLayout(ear_ranges, len(vertices_mm), len(faces), n_nodes, n_elements, sources,
                         tuple(frequencies.tolist()))


def read_counts(path: str | os.PathLike) -> tuple[int, list[str]]:
    """(declared count, data lines) of a Nodes.txt or Elements.txt."""
    text = Path(path).read_text()
    lines = text.split("\n")
    if lines[-1] == "":
        lines = lines[:-1]
    return int(lines[0]), lines[1:]
