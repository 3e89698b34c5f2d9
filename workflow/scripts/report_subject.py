"""Rule report_subject: the subject's HTML report with its figures (demo subjects: with the fidelity note
and the recovery of their true parameters)."""
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from reporting import write_subject_report  # noqa: E402

inputs = snakemake.input  # noqa: F821
note = json.loads(Path(inputs.demo).read_text())["note"] if "demo" in inputs.keys() else ""
write_subject_report(snakemake.wildcards.subject, Path("results") / snakemake.wildcards.subject,  # noqa: F821
                     snakemake.output.html, snakemake.output.figures,  # noqa: F821
                     note=note, truth=inputs.truth if "truth" in inputs.keys() else None,
                     timings_root="benchmarks/timings")
