"""Rules personal_detail and listener_detail: the personal-detail layer (ppm.align.detail) on a subject's (a
listener's ear's) PPM fit, towards the trusted parts of its whole scan (``evidence``: the crop or ear scan the fit's
target was cut from, so that the lobule and the skin ring the pinna segmentation drops count too; with the layer's
``hole_fill_mm`` set, joined with its screened Poisson reconstruction's fill of its holes): the posed PPM with
the layer (PLY, mm), the .blend with the layer as the shape key Personal_detail (weight 1), a summary and a distance
map of the fit's target (the segmented pinna) to the layered PPM."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

import bpy  # noqa: E402,F401  (before anything that may load pymeshlab)

import json  # noqa: E402

from ppm.align import prepare_target  # noqa: E402
from ppm.align.detail import DetailSettings, add_personal_detail  # noqa: E402
from ppm.align.report import one_sided_distances_mm  # noqa: E402
from core.atomic import write_text_atomic  # noqa: E402
from ppm.model import PinnaModel  # noqa: E402
from ppm.render import render_distance_map  # noqa: E402
from stitching.reconstruction import layer_evidence  # noqa: E402

inputs, out = snakemake.input, snakemake.output  # noqa: F821
model = PinnaModel.from_blend(inputs.blend)
target = prepare_target(inputs.target, side="left", segment=False)  # prepared already
# the packaged settings, or a listener's (config listener.personal_detail_settings); the evaluation's controls: packaged
settings = DetailSettings.packaged(**(snakemake.params.get("detail_settings") or {}))  # noqa: F821
scan = prepare_target(inputs.evidence, side=snakemake.params.side, segment=False)  # noqa: F821  (whole scan)
evidence = layer_evidence(scan, settings)  # with its reconstruction's fill of its holes where hole_fill_mm asks
detail, summary = add_personal_detail(model, evidence, settings, judged_on=target)
summary.update(target=inputs.target, evidence=inputs.evidence, evidence_surface=evidence.source, fit=inputs.blend)
model.export(out.aligned)
model.save_blend(out.blend)
distance = one_sided_distances_mm(target, model.evaluate(), model.faces)
render_distance_map(target.points_mm, None, distance, out.picture,
                    f"{snakemake.params.get('title') or snakemake.wildcards.subject}: "  # noqa: F821
                   "scan -> PPM with its personal detail")
write_text_atomic(out.summary, json.dumps(summary, indent=2) + "\n")
