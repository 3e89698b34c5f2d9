"""Rule report_subject: the subject's HTML report with its figures."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from reporting import write_subject_report  # noqa: E402

subject = snakemake.wildcards.subject  # noqa: F821
write_subject_report(subject, Path("results") / subject, snakemake.output.html, snakemake.output.figures)  # noqa: F821
