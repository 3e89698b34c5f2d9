"""Rule condition_distances: target <-> model distances of one evaluation condition's pinna (mm)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from reporting.evaluation import condition_distances  # noqa: E402

condition_distances(snakemake.input.target, snakemake.input.pinna, snakemake.output.summary,  # noqa: F821
                    snakemake.output.points)  # noqa: F821
