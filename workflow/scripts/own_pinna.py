"""Rule own_pinna_region: the head's own left pinna under the aligned PPM, cut out (the own_pinna control)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from stitching.pipeline import own_pinna_files  # noqa: E402

own_pinna_files(snakemake.input.head, snakemake.input.pinna, snakemake.output.pinna, snakemake.output.report)  # noqa: F821
