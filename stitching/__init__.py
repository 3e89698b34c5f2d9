"""Stitching the aligned PPM pinna onto a head mesh and remeshing it for BEM (millimetres, project
frame: +x front, +y left, +z up, origin at the interaural centre)."""
from mesh2hrtf_io.ear_canal import EarCanalError, ear_canal_elements
from .errors import StitchError
from .remesh import Band, remesh_graded, repair_self_intersections, self_intersections
from .replace_pinna import StitchedHead, own_pinna_region, replace_pinna
from .report import validate_head

__all__ = ["Band", "EarCanalError", "StitchError", "StitchedHead", "ear_canal_elements", "remesh_graded",
           "own_pinna_region", "repair_self_intersections", "replace_pinna", "self_intersections", "validate_head"]
