"""Rule make_demo_subject: one synthetic subject folder (scan crop, reference head, true parameters)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

import bpy  # noqa: E402,F401  (before pymeshlab)

from demo.subject import make_demo_subject  # noqa: E402
from stitching.remesh import bands_from_config  # noqa: E402

settings = snakemake.params.settings  # noqa: F821
make_demo_subject(Path(snakemake.output.scan).parent, snakemake.params.seed,  # noqa: F821
                  bands_from_config(settings["bands"]), parameter_fraction=settings["parameter_fraction"],
                  noise_mm=settings["noise_mm"], holes=settings["holes"], hole_radius_mm=settings["hole_radius_mm"],
                  outlier_share=settings["outlier_share"])
