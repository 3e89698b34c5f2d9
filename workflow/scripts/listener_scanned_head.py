"""Rule listener_scanned_head: a listener's head as scanned (both ears unchanged), remeshed at both ears as the
personal head is, refined where its fitted pinnae lie (the right fit a left-ear shape): the paper protocol's
reference head in a validation run (config listener.scanned_head)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from stitching.pipeline import remesh_files  # noqa: E402
from stitching.remesh import bands_from_config  # noqa: E402

inputs, output = snakemake.input, snakemake.output  # noqa: F821
remesh_files(inputs.head, inputs.left, output.mesh, output.report, bands_from_config(snakemake.params.bands),  # noqa: F821
             right_pinna_path=inputs.right)
