"""The average LEFT pinna template: its reproducible build from scans and its packaged default."""
from .build import EarScan, build_template, discover_scans
from .store import Template, default_template_dir, load_template, save_template

__all__ = ["EarScan", "Template", "build_template", "default_template_dir", "discover_scans", "load_template",
           "save_template"]
