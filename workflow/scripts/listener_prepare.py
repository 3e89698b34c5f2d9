"""Rule listener_prepare: a new listener's head scan into the project frame, closed, both pinnae cut out."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

import bpy  # noqa: E402,F401  (before pymeshlab)

from listener.prepare import prepare_head  # noqa: E402

prepare_head(snakemake.input.head, Path(snakemake.output.frame).parent)  # noqa: F821
