"""Rule export_project: a Mesh2HRTF project (NumCalc input) from a closed head mesh in millimetres."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from mesh2hrtf_io.hrtf_job import export_head_project  # noqa: E402

export_head_project(snakemake.input.head, snakemake.output.project, snakemake.params.settings,  # noqa: F821
                    snakemake.input.get("grid_sofa"), snakemake.params.title,  # noqa: F821
                    snakemake.params.head_store)  # noqa: F821
