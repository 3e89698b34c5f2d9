"""Rule band_head: a variant's head remeshed coarser for one frequency band, the ear-canal sources' faces kept
(stitching.frequency_bands)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from stitching.frequency_bands import write_band_head  # noqa: E402
from stitching.remesh import bands_from_config  # noqa: E402

inputs, output, params = snakemake.input, snakemake.output, snakemake.params  # noqa: F821
write_band_head(inputs.head, inputs.pinna, params.sides, bands_from_config(params.bands), output.mesh, output.sources)
