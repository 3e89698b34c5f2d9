"""Rule listener_report: a new listener's page (frame, both fits, HRTF planes, what personalising buys)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

import json  # noqa: E402

from core.atomic import write_text_atomic  # noqa: E402
import trimesh  # noqa: E402

from reporting.coverage import SEEN_MM, coverage_advice, coverage_picture, pinna_coverage  # noqa: E402
from reporting.listener import listener_localisation, plot_planes, write_listener_report  # noqa: E402
from reporting.pinna_regions import landmark_positions_mm  # noqa: E402

name = snakemake.wildcards.listener  # noqa: F821
inputs, out = snakemake.input, snakemake.output  # noqa: F821
# what each ear's scan saw, per region of its fitted pinna
coverage = {}
for side, pinna_path, target_path in zip(("left", "right"), inputs.pinnae, inputs.targets):
    pinna = trimesh.load(pinna_path, process=False, force="mesh")
    scan = trimesh.load(target_path, process=False, force="mesh")
    positions = landmark_positions_mm(pinna_path, inputs.landmarks)
    coverage[side] = pinna_coverage(pinna.vertices, pinna.faces, scan.vertices, positions)
    coverage_picture(pinna.vertices, pinna.faces, scan.vertices,
                     Path(out.html).parent / f"coverage_{side}.png", f"{name}, {side} ear: what the scan saw")
write_text_atomic(out.coverage, json.dumps({"seen_mm": SEEN_MM, "ears": coverage,
                                            "advice": coverage_advice(coverage)}, indent=1) + "\n")
localisation = listener_localisation(snakemake.input.hrtf, snakemake.params.others,  # noqa: F821
                                     snakemake.params.calibration_grid)  # noqa: F821
write_text_atomic(snakemake.output.localisation, json.dumps(localisation, indent=1) + "\n")  # noqa: F821
plot_planes(snakemake.input.hrtf, snakemake.output.planes, f"{name}: personal HRTF")  # noqa: F821
write_listener_report(name, Path(snakemake.input.frame).parent.parent, localisation,  # noqa: F821
                      snakemake.output.planes, snakemake.output.html,  # noqa: F821
                      personal_detail=bool(snakemake.params.personal_detail), coverage=coverage)  # noqa: F821
