"""Rule solve_numcalc_step: one frequency step of one ear with NumCalc (resumes finished steps)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from mesh2hrtf_io.hrtf_job import solve_numcalc_step  # noqa: E402

solve_numcalc_step(snakemake.input.project, int(snakemake.wildcards.source), int(snakemake.wildcards.step),  # noqa: F821
                   snakemake.output.status, snakemake.params.numcalc or None,  # noqa: F821
                   snakemake.params.max_iterations)  # noqa: F821
