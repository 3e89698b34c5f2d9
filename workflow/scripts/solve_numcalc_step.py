"""Rule solve_numcalc_step: a range of frequency steps of one ear with NumCalc (finished steps are kept)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from mesh2hrtf_io.hrtf_job import solve_numcalc_steps  # noqa: E402

wildcards = snakemake.wildcards  # noqa: F821
solve_numcalc_steps(snakemake.input.project, int(wildcards.source), range(int(wildcards.first), int(wildcards.last) + 1),  # noqa: F821
                    snakemake.output.status, snakemake.params.numcalc or None,  # noqa: F821
                    snakemake.params.max_iterations, snakemake.params.store)  # noqa: F821
