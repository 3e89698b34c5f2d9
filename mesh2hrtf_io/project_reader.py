"""Reading a Mesh2HRTF 1.2.4 project back: what the solvers and the SOFA collection need.

Everything is in metres (as stored in the project). Element order is the order of
``ObjectMeshes/Reference/Elements.txt``, in which each ear is one contiguous ID range.
"""
from __future__ import annotations

import dataclasses
import json
import os
import re
from pathlib import Path

import numpy as np

from .errors import Mesh2HrtfIoError
from .results import source_folders


@dataclasses.dataclass(frozen=True)
class GridData:
    """An evaluation grid: name, node IDs and (n, 3) points in metres."""

    name: str
    node_ids: np.ndarray
    points_m: np.ndarray


@dataclasses.dataclass(frozen=True)
class Source:
    """One reciprocal source folder (NumCalc/source_N): its ear and the vibrating element ID range."""

    folder: Path
    ear: str
    element_range: tuple[int, int]
    velocity_m_s: float

    @property
    def elements(self) -> np.ndarray:
        return np.arange(self.element_range[0], self.element_range[1] + 1)


@dataclasses.dataclass(frozen=True)
class Project:
    """A Mesh2HRTF project read from disk (SI units)."""

    folder: Path
    parameters: dict
    vertices_m: np.ndarray
    faces: np.ndarray
    grids: tuple[GridData, ...]
    sources: tuple[Source, ...]
    frequencies_hz: np.ndarray

    @property
    def speed_of_sound_m_s(self) -> float:
        return float(self.parameters["speedOfSound"])

    @property
    def density_kg_m3(self) -> float:
        return float(self.parameters["densityOfMedium"])

    @property
    def evaluation_points_m(self) -> np.ndarray:
        """All grid points in NC.inp order (grids sorted by name), as NumCalc concatenates them."""
        return np.concatenate([grid.points_m for grid in self.grids])


def _read_table(path: Path, columns: int) -> np.ndarray:
    if not path.is_file():
        raise Mesh2HrtfIoError(f"{path}: missing; the project is incomplete (export it again)")
    lines = path.read_text().split("\n")
    try:
        count = int(lines[0])
        rows = [line.split(" ") for line in lines[1:] if line.strip() and not line.startswith("#")]
        table = np.array(rows, dtype=np.float64)
    except ValueError as exc:
        raise Mesh2HrtfIoError(f"{path}: not a Mesh2HRTF node/element table ({exc})") from exc
    if table.shape != (count, columns):
        raise Mesh2HrtfIoError(f"{path}: header says {count} rows of {columns} columns, found {table.shape}")
    return table


_BOUNDARY = re.compile(r"^ELEM (\d+) TO (\d+) VELO ([0-9.eE+-]+)")


def _read_source(folder: Path) -> Source:
    nc_inp = folder / "NC.inp"
    if not nc_inp.is_file():
        raise Mesh2HrtfIoError(f"{nc_inp}: missing")
    lines = nc_inp.read_text().split("\n")
    ear = "left"
    for index, line in enumerate(lines):
        match = _BOUNDARY.match(line)
        if match:
            label = lines[index - 1].lower() if index else ""
            ear = "right" if "right" in label else "left"
            return Source(folder, ear, (int(match.group(1)), int(match.group(2))), float(match.group(3)))
    raise Mesh2HrtfIoError(f"{nc_inp}: no 'ELEM a TO b VELO v' boundary line: the ear source is missing")


def read_project(folder: str | os.PathLike) -> Project:
    """Read nodes, elements, grids, sources and parameters of a project folder."""
    folder = Path(folder)
    parameters_file = folder / "parameters.json"
    if not parameters_file.is_file():
        raise Mesh2HrtfIoError(f"{folder}: no parameters.json; not a Mesh2HRTF project folder")
    try:
        parameters = json.loads(parameters_file.read_text())
    except json.JSONDecodeError as exc:
        raise Mesh2HrtfIoError(f"{parameters_file}: not valid JSON ({exc})") from exc
    for key in ("frequencies", "speedOfSound", "densityOfMedium", "sourceType", "sourceArea", "evaluationGrids"):
        if key not in parameters:
            raise Mesh2HrtfIoError(f"{parameters_file}: key {key!r} is missing")
    nodes = _read_table(folder / "ObjectMeshes" / "Reference" / "Nodes.txt", 4)
    elements = _read_table(folder / "ObjectMeshes" / "Reference" / "Elements.txt", 7)
    if not np.array_equal(nodes[:, 0], np.arange(len(nodes))):
        raise Mesh2HrtfIoError(f"{folder}: object node IDs must run 0..N-1")
    grids = []
    for name in sorted(parameters["evaluationGrids"]):
        grid_nodes = _read_table(folder / "EvaluationGrids" / name / "Nodes.txt", 4)
        grids.append(GridData(name, grid_nodes[:, 0].astype(np.int64), grid_nodes[:, 1:]))
    source_dirs = source_folders(folder / "NumCalc")
    if not source_dirs:
        raise Mesh2HrtfIoError(f"{folder}/NumCalc: no source_N folders")
    return Project(folder, parameters, nodes[:, 1:], elements[:, 1:4].astype(np.int64), tuple(grids),
                   tuple(_read_source(d) for d in source_dirs), np.asarray(parameters["frequencies"], np.float64))
