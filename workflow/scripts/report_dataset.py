"""Rule report_dataset: all subjects side by side, the summary CSV, parameter ranges and population
figures."""
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from reporting import write_dataset_report  # noqa: E402

inputs, output = snakemake.input, snakemake.output  # noqa: F821
note = json.loads(Path(inputs.demo).read_text())["note"] if "demo" in inputs.keys() else ""
write_dataset_report(Path("results"), list(snakemake.params.subjects), output.html, output.csv,  # noqa: F821
                     output.figures, out_parameters_csv=output.parameters, note=note,
                     timings_root="benchmarks/timings")
