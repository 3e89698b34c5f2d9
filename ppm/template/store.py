"""Reading and writing a pinna template: mesh, landmarks and provenance (millimetres, project frame).

A template folder holds `template_left.ply` (vertex order is the common topology), and
`provenance.json` (which scans, which licence, which settings). The default template ships inside
the package under `ppm/template/resources/`.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import trimesh

from core.atomic import write_text_atomic
from ..errors import PpmError
from ..mesh_io import check_left_side, load_mesh, write_mesh

RESOURCES = Path(__file__).resolve().parent / "resources"
MESH_NAME = "template_left.ply"
PROVENANCE_NAME = "provenance.json"


@dataclasses.dataclass(frozen=True)
class Template:
    """A template pinna: (n, 3) float vertices in mm, (m, 3) int faces, its provenance dict and folder."""

    vertices_mm: np.ndarray
    faces: np.ndarray
    provenance: dict
    folder: Path | None = None

    @property
    def mesh(self) -> trimesh.Trimesh:
        return trimesh.Trimesh(self.vertices_mm, self.faces, process=False)


def default_template_dir() -> Path:
    """Folder of the template shipped with the package."""
    return RESOURCES


def load_template(folder: str | Path | None = None) -> Template:
    """Load a template folder (default: the packaged one).

    Raises
    ------
    PpmError
        If the folder lacks the mesh or the provenance file, or the mesh is not a left pinna.
    """
    folder = Path(folder) if folder is not None else RESOURCES
    mesh_path, provenance_path = folder / MESH_NAME, folder / PROVENANCE_NAME
    for path in (mesh_path, provenance_path):
        if not path.is_file():
            raise PpmError(f"{path}: missing; a template folder needs {MESH_NAME} and {PROVENANCE_NAME} "
                           "(build one with `ppm build-template`)")
    mesh = load_mesh(mesh_path)
    check_left_side(mesh, source=str(mesh_path))
    provenance = json.loads(provenance_path.read_text(encoding="utf-8"))
    return Template(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64), provenance, folder)


def save_template(folder: str | Path, template: Template) -> Path:
    """Write a template folder atomically file by file; returns the folder."""
    folder = Path(folder)
    write_mesh(folder / MESH_NAME, template.vertices_mm, template.faces)
    write_text_atomic(folder / PROVENANCE_NAME, json.dumps(template.provenance, indent=2) + "\n")
    return folder
