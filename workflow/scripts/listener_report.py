"""Rule listener_report: a new listener's page (frame, both fits, HRTF planes, what personalising buys)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

import json  # noqa: E402

from core.atomic import write_text_atomic  # noqa: E402

from reporting.listener import listener_localisation, plot_planes, write_listener_report  # noqa: E402

name = snakemake.wildcards.listener  # noqa: F821
inputs, out = snakemake.input, snakemake.output  # noqa: F821
coverage = json.loads(Path(inputs.coverage).read_text())["ears"]  # rule listener_coverage
localisation = listener_localisation(snakemake.input.hrtf, snakemake.params.others,  # noqa: F821
                                     snakemake.params.calibration_grid)  # noqa: F821
write_text_atomic(snakemake.output.localisation, json.dumps(localisation, indent=1) + "\n")  # noqa: F821
plot_planes(snakemake.input.hrtf, snakemake.output.planes, f"{name}: personal HRTF")  # noqa: F821
write_listener_report(name, Path(snakemake.input.frame).parent.parent, localisation,  # noqa: F821
                      snakemake.output.planes, snakemake.output.html,  # noqa: F821
                      personal_detail=bool(snakemake.params.personal_detail), coverage=coverage)  # noqa: F821
