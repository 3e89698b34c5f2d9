"""Rule collect_sofa: HRTF and HRIR SOFA files of a solved project (the steps solved on band meshes merged in
first)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from mesh2hrtf_io.hrtf_job import collect, merge_band_steps  # noqa: E402

if snakemake.params.band_steps:  # noqa: F821
    merge_band_steps(snakemake.input.project, snakemake.params.band_steps)  # noqa: F821
collect(snakemake.input.project, snakemake.output.hrtf, snakemake.output.hrir, snakemake.params.hrir)  # noqa: F821
