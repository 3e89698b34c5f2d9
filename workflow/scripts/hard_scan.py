"""Rule hard_scan: one fixed defective scan of a subject's clean left crop (ppm.align.defects at config
evaluation.hard_scan.level, drawn with the subject's own seed), in the head frame and millimetres, for the
evaluation's *_hard conditions; kept with the evaluation's results."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

import bpy  # noqa: E402,F401  (before pymeshlab, which the resampling uses)

import json  # noqa: E402

from ppm.align.defects import hard_scan_of  # noqa: E402
from core.atomic import write_text_atomic  # noqa: E402
from ppm.mesh_io import write_mesh  # noqa: E402

settings = snakemake.params.settings  # noqa: F821
scan, report = hard_scan_of(snakemake.input.crop, snakemake.wildcards.subject, settings["level"],  # noqa: F821
                            int(settings["seed"]))
write_mesh(snakemake.output.scan, scan.vertices, scan.faces)  # noqa: F821
write_text_atomic(snakemake.output.report, json.dumps(report, indent=2) + "\n")  # noqa: F821
