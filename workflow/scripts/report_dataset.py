"""Rule report_dataset: all subjects side by side, the summary CSV and population figures."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from reporting import write_dataset_report  # noqa: E402

write_dataset_report(Path("results"), list(snakemake.params.subjects), snakemake.output.html,  # noqa: F821
                     snakemake.output.csv, snakemake.output.figures)  # noqa: F821
