"""Rule build_template: the average left pinna of data_root without one subject (common topology)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from ppm.template.build import build_template_folder  # noqa: E402
from ppm.template.store import default_template_dir  # noqa: E402

settings = snakemake.params.settings  # noqa: F821
build_template_folder(
    snakemake.input.data_root,  # noqa: F821
    Path(snakemake.output.mesh).parent,  # noqa: F821
    exclude=[snakemake.wildcards.subject],  # noqa: F821
    topology_dir=default_template_dir(),
    edge_mm=settings["edge_mm"],
    margin_mm=settings["margin_mm"],
    rounds=settings["rounds"],
)
