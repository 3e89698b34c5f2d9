# Config validation, wildcard constraints and input functions (no rules here).
from pathlib import Path

from snakemake.utils import validate

validate(config, "../config/schema.yaml")

DATA_ROOT = Path(config["data_root"]) if config["data_root"] else None
if DATA_ROOT is not None and not DATA_ROOT.is_dir():
    raise ValueError(
        f"config key data_root={config['data_root']!r}: no such folder; give a dataset folder of "
        "<subject>/pinna_left_crop.ply, or leave data_root empty for the bundled default"
    )
SUBJECTS = (
    sorted(p.name for p in DATA_ROOT.iterdir() if (p / "pinna_left_crop.ply").is_file())
    if DATA_ROOT is not None
    else []
)
if DATA_ROOT is not None and not SUBJECTS:
    raise ValueError(
        f"config key data_root={config['data_root']!r}: no <subject>/pinna_left_crop.ply under it; "
        "point data_root to a dataset folder or leave it empty for the bundled default"
    )


wildcard_constraints:
    subject="|".join(SUBJECTS) if SUBJECTS else "[A-Za-z0-9_-]+",


def template_params():
    """Settings of the template build, from config/template."""
    return config["template"]


def get_final_output():
    """Everything `snakemake --cores 2` makes: PPM pictures, and with a dataset the leave-one-subject-out
    templates and the alignment of every subject."""
    out = [
        "results/ppm/default_ppm.png",
        "results/ppm/range_sheet.png",
        "results/ppm/default_ppm.blend",
        "results/ppm/default_parameters.csv",
    ]
    out += [f"results/{s}/align/summary.json" for s in SUBJECTS]
    return out
