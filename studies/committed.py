"""The committed evaluation files a benchmark reads: localisation settings, a subject's reference SOFA and its
solved left-ear HRTF files by condition (``evaluation/sonicom/sofa``), with the unchanged head (or another base) required."""
from __future__ import annotations

import argparse
from pathlib import Path

# a clean crop point counts as seen by a defective scan when a scan point lies this close (mm); defined once
from reporting.stitched_region import SEEN_MM

ROOT = Path(__file__).resolve().parents[1]
SONICOM = ROOT.parent / "shared" / "data" / "sonicom"


def committed_subject(evaluation: Path, subject: str,
                      needs: tuple[str, ...] = ("original",)) -> tuple[dict, Path, dict[str, Path]]:
    """(config localisation settings, the subject's reference SOFA, condition -> left-ear HRTF file); exits with
    a message naming the folder when none of the conditions ``needs`` (by default the unchanged head,
    ``original``) is there."""
    import yaml

    from reporting.evaluation_files import left_hrtf_files

    settings = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["localisation"]
    files = left_hrtf_files(evaluation / "sofa", subject)
    if not any(name in files for name in needs):
        raise SystemExit(f"{evaluation}/sofa: no solve of {subject} as condition {' or '.join(needs)}")
    return settings, SONICOM / subject / settings["reference_sofa"], files


def crop_seen_by_hard_scan(evaluation: Path, subject: str):
    """The subject's clean left crop (the truth; trimesh, mm, project frame) and, per crop vertex, whether the
    evaluation's fixed hard scan (``<evaluation>/hard_scans/<subject>_hard_scan.ply``) has a point within
    :data:`SEEN_MM` of it."""
    import trimesh
    from scipy.spatial import cKDTree

    scan = trimesh.load(evaluation / "hard_scans" / f"{subject}_hard_scan.ply", process=False, force="mesh")
    crop = trimesh.load(SONICOM / subject / "pinna_left_crop.ply", process=False, force="mesh")
    return crop, cKDTree(scan.vertices).query(crop.vertices)[0] < SEEN_MM


def require_workflow_files(*paths: Path) -> None:
    """Exit with the Snakemake command that makes them when any of ``paths`` (files the paper's workflow makes under
    ``results/``) is missing."""
    import sys

    for path in paths:
        if not path.is_file():
            sys.exit(f"{path}: missing; make it with `.venv/bin/python -m snakemake --cores 2 --configfile "
                     f"config/paper_sonicom.yaml -- {path.relative_to(ROOT)}`")


def subject_parser(description: str) -> argparse.ArgumentParser:
    """A parser of ``--evaluation`` (the committed evaluation folder) and ``--subject`` (default P143), for a study
    to add its own options to."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--evaluation", type=Path, default=ROOT / "evaluation" / "sonicom")
    parser.add_argument("--subject", default="P143")
    return parser


def subject_arguments(description: str) -> argparse.Namespace:
    """``--evaluation`` and ``--subject`` (:func:`subject_parser`) from the command line."""
    return subject_parser(description).parse_args()
