"""Rule scan_hard_pinna: the fixed defective scan made watertight (screened Poisson) and cut under the rim of the PPM
fitted to it (the scan_hard control)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from stitching.pipeline import scan_pinna_files  # noqa: E402

scan_pinna_files(snakemake.input.scan, snakemake.input.guide, snakemake.output.pinna,  # noqa: F821
                 snakemake.output.report, snakemake.output.surface)  # noqa: F821
