"""Rule remesh: graded remeshing for BEM and the validation report."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from stitching.pipeline import remesh_files  # noqa: E402
from stitching.remesh import bands_from_config  # noqa: E402

bands = bands_from_config(snakemake.params.bands)  # noqa: F821
remesh_files(snakemake.input.mesh, snakemake.input.pinna, snakemake.output.mesh, snakemake.output.report,  # noqa: F821
             bands, right_pinna_path=snakemake.input.get("right_pinna"))  # noqa: F821
