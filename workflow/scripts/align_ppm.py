"""Rules align_ppm, listener_align and place_default_ppm: fit the PPM (leave-one-subject-out template; the packaged
one for a listener) to a subject's prepared left pinna scan (a listener's left or mirrored right one), or (params.global_pose_only, the evaluation's default_ppm control) only place the template at
default parameters by the global pose. With the whole scan the target was cut from (input ``scan``), a fit whose
target the segmentation left part of the pinna out of is done again on the scan around it (ppm.align.widen)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

import bpy  # noqa: E402,F401  (before anything that may load pymeshlab)

import dataclasses  # noqa: E402
import json  # noqa: E402

from ppm.align import AlignSettings, align, prepare_target  # noqa: E402
from ppm.align.pose_by_fit import align_any_pose, pose_summary  # noqa: E402
from ppm.align.report import one_sided_distances_mm, write_alignment  # noqa: E402
from ppm.align.target import with_scan  # noqa: E402
from ppm.align.widen import refit_widened  # noqa: E402
from ppm.model import PinnaModel  # noqa: E402
from ppm.render import render_distance_map  # noqa: E402

out_dir = Path(snakemake.output.summary).parent  # noqa: F821
model = PinnaModel.from_template(Path(snakemake.input.template).parent)  # noqa: F821
target = prepare_target(snakemake.input.target, side="left", segment=False)  # noqa: F821  (prepared already)
global_pose_only = bool(snakemake.params.get("global_pose_only", False))  # noqa: F821
report = snakemake.input.get("report")  # noqa: F821
scan = snakemake.input.get("scan")  # noqa: F821
if scan:
    target = with_scan(target, scan)
pose = json.loads(Path(report).read_text(encoding="utf-8")).get("pose") if report else None
if pose is not None and not global_pose_only:  # a scan given in any pose: the PPM decides between close poses
    result, target = align_any_pose(model, dataclasses.replace(target, pose=pose))
else:
    result = align(model, target, AlignSettings(stages=()) if global_pose_only else None)
widening = None
if scan and not global_pose_only:
    result, target, widening = refit_widened(model, target, result)
write_alignment(out_dir, model, target, result, extra={"template": snakemake.input.template,  # noqa: F821
                                                       "global_pose_only": global_pose_only,
                                                       "target_widening": widening,
                                                       **pose_summary(target)})
distance = one_sided_distances_mm(target, result.vertices_mm, model.faces)
render_distance_map(target.points_mm, None, distance, snakemake.output.picture,  # noqa: F821
                    f"{snakemake.params.get('title') or snakemake.wildcards.subject}: scan -> "  # noqa: F821
                    f"{'placed default' if global_pose_only else 'aligned'} PPM")
