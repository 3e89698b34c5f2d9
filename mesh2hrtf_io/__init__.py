"""Mesh2HRTF project export (NumCalc input) from head meshes in millimetres; metres inside projects."""
from .checks import check_mesh, mesh_problems
from .errors import Mesh2HrtfIoError
from .grids import EvaluationGrid, grid_from_sofa, ring_grid, sagittal_grid, sphere_grid
from .project import ProjectLayout, write_project

__all__ = ["EvaluationGrid", "Mesh2HrtfIoError", "ProjectLayout", "check_mesh", "grid_from_sofa", "mesh_problems",
           "ring_grid", "sagittal_grid", "sphere_grid", "write_project"]
