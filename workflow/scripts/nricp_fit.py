"""Rule nricp_hard: the template (leave-one-subject-out) deformed by free-form non-rigid ICP onto a prepared scan
(ppm.align.nricp, the schedule benchmarks/align_defects.py found best), the evaluation's per-vertex comparison for
the PPM and its personal-detail layer: the fitted pinna (PLY, mm, the template's vertices and faces), a summary
and a distance map."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

import bpy  # noqa: E402,F401  (before anything that may load pymeshlab)

import json  # noqa: E402
import time  # noqa: E402

import trimesh  # noqa: E402

from ppm.align import prepare_target  # noqa: E402
from ppm.align.nricp import NRICP_SCHEDULE, nricp_fit  # noqa: E402
from ppm.align.report import distance_summary, one_sided_distances_mm  # noqa: E402
from ppm.align.target import surface_without_outliers  # noqa: E402
from core.atomic import write_text_atomic  # noqa: E402
from ppm.mesh_io import write_mesh  # noqa: E402
from ppm.render import render_distance_map  # noqa: E402
from ppm.template.store import load_template  # noqa: E402

inputs, out = snakemake.input, snakemake.output  # noqa: F821
template = load_template(Path(inputs.template).parent)
target = prepare_target(inputs.target, side="left", segment=False)  # prepared already
start = time.perf_counter()
vertices = nricp_fit(trimesh.Trimesh(template.vertices_mm, template.faces, process=False),
                     surface_without_outliers(target))
seconds = time.perf_counter() - start
write_mesh(out.aligned, vertices, template.faces)
distance = one_sided_distances_mm(target, vertices, template.faces)
render_distance_map(target.points_mm, None, distance, out.picture,
                    f"{snakemake.wildcards.subject}: scan -> NRICP template")  # noqa: F821
write_text_atomic(out.summary, json.dumps({
    "target": inputs.target, "template": inputs.template, "schedule": [list(step) for step in NRICP_SCHEDULE],
    "distance_target_to_nricp": distance_summary(distance), "seconds": round(seconds, 2)}, indent=2) + "\n")
