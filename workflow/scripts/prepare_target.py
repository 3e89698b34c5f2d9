"""Rules prepare_target and listener_target: check a subject's left pinna scan (a listener's left or right one) (units, side, NaNs) or, with align.scan_pose: any,
find its pose, unit and side; cut the pinna with a ring of skin out of the crop, and report outliers and holes."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from ppm.align.target import prepare_target, write_target  # noqa: E402

target = prepare_target(snakemake.input.scan, side=snakemake.params.get("side", "left"),  # noqa: F821
                        margin_mm=snakemake.params.settings["target_margin_mm"],  # noqa: F821
                        scan_pose=snakemake.params.settings.get("scan_pose", "project_frame"))  # noqa: F821
write_target(target, snakemake.output.target, snakemake.output.report,  # noqa: F821
             snakemake.output.get("scan"))  # noqa: F821  (the whole scan in the same frame, for ppm.align.widen)
