"""Rule listener_ear_scan: a listener's separate ear scan registered onto the ear of its head, or placed by the head's
frame where the scan shares the head scan's coordinates (config listeners: ear_scan_frame: head)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

import json  # noqa: E402

import trimesh  # noqa: E402

import numpy as np  # noqa: E402

from listener.ear_scan import place_ear_scan, register_ear_scan  # noqa: E402
from listener.errors import ListenerError  # noqa: E402
from core.atomic import write_text_atomic  # noqa: E402
from ppm.errors import PpmError  # noqa: E402
from ppm.mesh_io import load_mesh, write_mesh  # noqa: E402

side = snakemake.wildcards.side  # noqa: F821
try:
    scan = load_mesh(snakemake.input.scan)  # noqa: F821
except PpmError as error:
    raise ListenerError(str(error)) from error
crop = trimesh.load(snakemake.input.crop, process=False, force="mesh")  # noqa: F821
if snakemake.params.ear_scan_frame == "head":  # noqa: F821
    frame = json.loads(Path(snakemake.input.frame).read_text(encoding="utf-8"))  # noqa: F821
    registered, summary = place_ear_scan(scan, np.asarray(frame["matrix"]), frame["unit"], crop, side,  # noqa: F821
                                         str(snakemake.input.scan))  # noqa: F821
else:
    registered, summary = register_ear_scan(scan, crop, side, str(snakemake.input.scan))  # noqa: F821
write_mesh(snakemake.output.mesh, registered.vertices, registered.faces)  # noqa: F821
write_text_atomic(snakemake.output.report, json.dumps({"scan": str(snakemake.input.scan), **summary}, indent=1) + "\n")  # noqa: F821
