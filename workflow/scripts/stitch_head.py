"""Rules stitch and listener_stitch: replace the head's left pinna (a listener's both) by the aligned PPM pinna."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from stitching.pipeline import stitch_files  # noqa: E402

stitch_files(snakemake.input.head, snakemake.input.pinna, snakemake.output.mesh, snakemake.output.report,  # noqa: F821
             gap_mm=snakemake.params.gap_mm, right_pinna_path=snakemake.input.get("right_pinna"))  # noqa: F821
