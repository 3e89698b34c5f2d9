"""Demo subjects: what the workflow runs on when no dataset is configured (millimetres, project frame).

A demo subject is laid out like a dataset subject folder:

- ``pinna_left_crop.ply``: a scan-like crop of the left ear and the skin around it, made from the head
  below with noise along the normals, holes and outliers (see `ppm.align.synthetic.add_scan_defects`);
- ``head_graded_left.ply``: the reference head, remeshed for BEM with the given bands;
- ``truth_parameters.json`` / ``.csv``: the PPM parameters its ears were made with (the ground truth);
- ``demo.json``: how it was made (seed, settings), and that it is demo fidelity.

The pinna is the packaged default PPM posed with random parameters from the typical spread; the head
is the parametric head of `demo.head` with that pinna on both sides.
"""
from __future__ import annotations

import json
import logging
import os
from pathlib import Path

import numpy as np
import trimesh

from ppm.align.synthetic import add_scan_defects
from core.atomic import write_text_atomic
from ppm.mesh_io import write_mesh
from ppm.model import PinnaModel
from ppm.parameters import random_parameters
from mesh2hrtf_io.ear_canal import ear_canal_elements
from stitching.loops import boundary_loops
from stitching.remesh import Band, fill_folds, remesh_graded, repair_self_intersections
from stitching.report import validate_head

from .head import HeadShape, head_with_pinnae

log = logging.getLogger(__name__)

#: Shown in every demo report.
DEMO_NOTE = ("Demo fidelity: a synthetic subject (a PPM ear with random parameters and scan-like defects on a "
             "parametric ellipsoid head), meshed coarsely and solved at a few frequencies so the whole pipeline "
             "runs in minutes. Its HRTFs and localisation predictions show that every stage works; they are not "
             "research results. Run with --config data_root=<dataset> for the real evaluation.")
#: Radius (mm, from the centre of the pinna's rim) of the scan crop around the ear.
CROP_RADIUS_MM = 48.0
#: Longest edge (mm) of the scan crop: the coarse head skin is subdivided to scan-like density.
CROP_EDGE_MM = 1.2


def scan_crop(head: trimesh.Trimesh, pinna: trimesh.Trimesh, radius_mm: float = CROP_RADIUS_MM) -> trimesh.Trimesh:
    """The left ear and the skin around it, cut from ``head`` like a hand-held scan of the ear (mm)."""
    rim_centre = np.asarray(pinna.vertices)[boundary_loops(pinna)[0]].mean(axis=0)
    centres = head.triangles_center
    keep = (np.linalg.norm(centres - rim_centre, axis=1) < radius_mm) & (centres[:, 1] > 20.0)
    crop = trimesh.Trimesh(head.vertices, head.faces[keep], process=False)
    crop.remove_unreferenced_vertices()
    vertices, faces = trimesh.remesh.subdivide_to_size(crop.vertices, crop.faces, max_edge=CROP_EDGE_MM)
    components = trimesh.Trimesh(vertices, faces, process=True).split(only_watertight=False)
    return max(components, key=lambda part: len(part.faces))


def make_demo_subject(out_dir: str | os.PathLike, seed: int, bands: list[Band], *, parameter_fraction: float = 0.4,
                      noise_mm: float = 0.2, holes: int = 3, hole_radius_mm: float = 4.0,
                      outlier_share: float = 0.02, model: PinnaModel | None = None,
                      shape: HeadShape = HeadShape()) -> dict:
    """Write one demo subject folder (see the module docstring). Returns its description (demo.json)."""
    out = Path(out_dir)
    rng = np.random.default_rng(seed)
    model = model or PinnaModel.from_template()
    truth = random_parameters(rng, parameter_fraction)
    pinna = model.mesh(truth)
    head = head_with_pinnae(pinna, shape)
    crop = scan_crop(head, pinna)
    on_pinna = np.flatnonzero(trimesh.proximity.ProximityQuery(pinna).signed_distance(crop.vertices) > -0.5)
    scan = add_scan_defects(crop, rng, noise_mm=noise_mm, holes=holes, hole_radius_mm=hole_radius_mm,
                            outlier_share=outlier_share, hole_centres=on_pinna)
    graded = fill_folds(repair_self_intersections(remesh_graded(head, np.asarray(pinna.vertices), bands)))
    report = validate_head(graded, pinna)
    for side in ("left", "right"):
        ear_canal_elements(graded, side, source=f"{out}/head_graded_left.ply")
    if not report["ok"]:
        raise RuntimeError(f"demo head for seed {seed} is not fit for BEM: {report['problems']}")
    description = {
        "fidelity": "demo", "note": DEMO_NOTE, "seed": seed, "parameter_fraction": parameter_fraction,
        "scan": {"noise_mm": noise_mm, "holes": holes, "hole_radius_mm": hole_radius_mm,
                 "outlier_share": outlier_share, "n_vertices": len(scan.vertices)},
        "head": {"shape_mm": {"front": shape.front_mm, "side": shape.side_mm, "top": shape.top_mm,
                              "centre_z": shape.centre_z_mm},
                 "n_triangles": int(len(graded.faces)),
                 "pinna_edge_median_mm": report["pinna_edge_mm"]["median"],
                 "max_frequency_hz_6_per_wavelength": report["max_frequency_hz_6_per_wavelength"]},
    }
    out.mkdir(parents=True, exist_ok=True)
    truth.write(out / "truth_parameters.json")
    truth.write(out / "truth_parameters.csv")
    write_mesh(out / "pinna_left_crop.ply", scan.vertices, scan.faces)
    write_mesh(out / "head_graded_left.ply", graded.vertices, graded.faces)
    write_text_atomic(out / "demo.json", json.dumps(description, indent=2) + "\n")
    log.info("demo subject %s (seed %d): scan %d points, head %d triangles", out.name, seed, len(scan.vertices),
             len(graded.faces))
    return description
