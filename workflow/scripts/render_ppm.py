"""Rule render_ppm: pictures, .blend and parameter table of the default PPM (packaged template)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from ppm.model import PinnaModel  # noqa: E402
from ppm.render import render_model, render_range_sheet  # noqa: E402

model = PinnaModel.from_template()
render_model(model, snakemake.output.picture)  # noqa: F821
render_range_sheet(model, snakemake.output.sheet)  # noqa: F821
model.save_blend(snakemake.output.blend)  # noqa: F821
model.write_parameters(snakemake.output.parameters)  # noqa: F821
