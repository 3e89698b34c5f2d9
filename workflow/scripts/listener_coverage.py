"""Rule listener_coverage: what each ear's scan saw, per region of its fitted pinna (share of area with a scan point
within reporting.coverage.SEEN_MM), a picture per ear and plain advice where a region was not seen."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from reporting.coverage import write_coverage  # noqa: E402

inputs, out = snakemake.input, snakemake.output  # noqa: F821
write_coverage(snakemake.wildcards.listener, dict(zip(("left", "right"), inputs.pinnae)),  # noqa: F821
               dict(zip(("left", "right"), inputs.targets)), inputs.landmarks, out.coverage)
