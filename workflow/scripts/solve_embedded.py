"""Rule solve_embedded: every step of a project with the embedded bempp-cl solver (resumable)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from mesh2hrtf_io.hrtf_job import solve_embedded  # noqa: E402

solve_embedded(snakemake.input.project, snakemake.output.status, snakemake.params.store)  # noqa: F821
