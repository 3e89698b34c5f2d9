"""Rule listener_coverage: what each ear's scan saw, per region of its fitted pinna (share of area with a point of the
whole ear scan, the personal-detail layer's evidence, within reporting.coverage.SEEN_MM), a picture per ear and plain
advice where a region was not seen."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from ppm.align import prepare_target  # noqa: E402
from reporting.coverage import write_coverage  # noqa: E402

inputs, out = snakemake.input, snakemake.output  # noqa: F821
sides = ("left", "right")
scans = {side: prepare_target(path, side=side, segment=False).points_mm for side, path in zip(sides, inputs.scans)}
write_coverage(snakemake.wildcards.listener, dict(zip(sides, inputs.pinnae)), scans,  # noqa: F821
               inputs.landmarks, out.coverage)
