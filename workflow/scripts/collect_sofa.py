"""Rule collect_sofa: HRTF and HRIR SOFA files of a solved project."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from mesh2hrtf_io.hrtf_job import collect  # noqa: E402

collect(snakemake.input.project, snakemake.output.hrtf, snakemake.output.hrir, snakemake.params.hrir)  # noqa: F821
