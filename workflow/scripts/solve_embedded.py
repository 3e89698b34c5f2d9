"""Rule solve_embedded: every step of a subject's projects (its heads) with the embedded bempp-cl solver in one
process, so that bempp-cl builds its kernels once (resumable)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from mesh2hrtf_io.hrtf_job import solve_embedded  # noqa: E402

params = snakemake.params  # noqa: F821
solve_embedded(dict(zip(params.variants, snakemake.input.projects)), snakemake.output.status,  # noqa: F821
               params.stores, snakemake.threads, params.device)  # noqa: F821
