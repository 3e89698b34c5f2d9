"""A SONICOM subject treated as a new listener (issues 42, 54): its head, with both ears as finely resolved as the
dataset has them (listener.dataset_heads.both_ears_head), turned at random and written in centimetres, no separate
ear scans, the PPM template built without it; through the listener workflow end to end with NumCalc (both ears,
a mesh per frequency band, the personal-detail layer on, the full grid with the dataset's 793 directions added),
and its head as scanned solved the same way (listener.scanned_head), then judged:

- the head frame found against the dataset's frame (the pose applied is known): axis and origin errors;
- both PPM fits: median distance from the ear crop to the fitted PPM (mm); each ear's scan coverage;
- NumCalc CPU hours of both ears, personal and reference heads (the step statuses kept in the step store);
- the paper's protocol: the head as scanned is reference and template, S calibrated to 8 % QE on it, the personal
  set heard with it on the dataset's 793 directions, both ears and each alone
  (reporting.paper_protocol.both_ears_protocol), with the split by sagittal plane;
- the second line, the evaluation's earlier protocol: the dataset's reference HRIRs are the template;
- with --hard, the listener <subject>_hard: the same posed head, both ears fitted to hard scans given as its
  separate ear scans (independent fixed draws), judged against <subject>_new's head as scanned;
- with --hard --no-layer, the listener <subject>_hard_ppm: the same hard scans and fits, the PPM without the
  personal-detail layer, judged the same way (whether the layer brings the hard listener nearer its own ears);
- with --hard --placed, the listener <subject>_hard_placed: the same hard scans, taken to share the head scan's
  coordinates (ear_scan_frame: head) and placed by the head's frame instead of registered, as a head scan whose ear
  regions are the hard scans has them (benchmarks/ear_scan_placement.py: registration leaves them 0.24-0.58 mm off);
- with --hard --placed --no-layer, the listener <subject>_hard_ppm_placed: the same placed scans without the layer
  (whether the layer brings the placed hard listener nearer its own ears: hard_placed_layer_nearer);
- with --hard --oracle, the listener <subject>_hard_oracle_placed: the placed, layered listener whose hard scans are
  completed by the truth where they were blind (reporting.stitched_region.completed_where_blind: the clean crop, its
  vertices the scan saw moved onto the scan): what the parts the scans were blind to cost the hard listener (unseen_share_of_hard_placed_gap: the share of hard_placed's both-ear delta QE and PE that
  the completed scans take away); with --draw N the same on another draw of the scans (hard_oracle_placed_draw<N>;
  unseen_share_of_hard_placed_gap_draws, and hard_oracle_placed_draws_mean: how near a layer that followed the
  scans exactly where they saw could come, over the draws);
- with --hard --blind-oracle, the listener <subject>_hard_blind_oracle_placed: the placed, layered listener whose hard
  scans are completed by the truth where they were blind and keep their own heights where they saw
  (reporting.stitched_region.heights_where_seen: each seen vertex of the clean crop moved along its normal onto the
  scan, not to its closest point, which leaves less of the scan's noise than the scan has): near what a perfect guess
  of the unseen parts alone is worth; unseen_parts_share_of_hard_placed_gap;
- with --hard --noise-floor, the listener <subject>_hard_noise_placed: the placed, layered listener whose layer ends
  its stiffness schedule at the scan's own noise (listener.personal_detail_settings: noise_stiffness_factor 1;
  studies/noise_stiffness.py): whether that geometric gain is an acoustic one;
- with --hard --supple-end, the listener <subject>_hard_supple_placed: the same, its layer's schedule taken one stage
  further, to 0.03 mm² (the opposite direction: a stiffer end cost QE twice);
- with --hard --layer-variant points, the listener <subject>_hard_points_placed: the supple end with the pull of the
  PPM's vertices towards the scan's triangulated surface weighted 0.3 (forward_weight), so that the scan's points
  lead rather than the chords between them;
- with --hard --placed --draw N, the listener <subject>_hard_placed_draw<N>: the placed, layered listener on another
  draw of the same hard recipe (seed + N): how far a hard listener's figures move with the scans' draw; with
  --layer-variant NAME --draw N, <subject>_hard_<NAME>_placed_draw<N>, the variant on that draw; the figures of a
  layer over the draws solved (hard_placed_draws_mean, hard_points_placed_draws_mean);
- with --layer-variant NAME alone, the listener <subject>_new_<NAME>: the clean head scan with the layer variant,
  judged against <subject>_new's head as scanned (whether a layer that brings the hard listener nearer keeps the
  clean one where it is);
- every solved personal head's ears against the head as scanned (<kind>_ears_to_scanned, mm).

The steps are kept in benchmarks/results/new_listener/steps_dataset_grid as they finish, so that a run stopped on the
way (or a fresh clone) continues from them. The posed head and the run's outputs stay in results/new_listener/ and
results/listeners/ (not committed: the head is the dataset's).

Run: .venv/bin/python benchmarks/new_listener.py [--subject P143] [--seed 7] [--cores 2]
     [--hard [--no-layer] [--placed] [--oracle | --blind-oracle] [--noise-floor | --supple-end] [--draw N]]
     [--layer-variant NAME]
     [--until remesh/validation.json] [--report-only]
Last line: JSON with paper_delta_qe_pp, paper_delta_pe_deg, paper_left_delta_qe_pp, paper_right_delta_qe_pp,
hard_paper_delta_qe_pp, hard_paper_delta_pe_deg, hard_ppm_paper_delta_qe_pp, hard_ppm_paper_delta_pe_deg,
hard_layer_nearer, hard_placed_paper_delta_qe_pp, hard_placed_paper_delta_pe_deg, hard_ppm_placed_paper_delta_qe_pp,
hard_ppm_placed_paper_delta_pe_deg, hard_placed_layer_nearer, coverage_left, coverage_right,
directions_compared, <kind>_ears_to_scanned,
reference_cpu_hours, cpu_hours (null where a solve has not finished), the frame and fit figures, the dataset-reference
line (delta_qe_pp, delta_pe_deg, <side>_ear_only_delta_qe_pp) and the split of another person's set by ear and plane.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SONICOM = ROOT.parent / "shared" / "data" / "sonicom"
KEPT = ROOT / "benchmarks" / "results" / "new_listener"
WORK = ROOT / "results" / "new_listener"
#: The steps of this benchmark's solves: both heads on the listener's full grid with the dataset's 793 directions
#: added (listener.dataset_grid). The first run's steps (personal head without the layer, full grid alone) stay in
#: KEPT / "steps" for the record.
STORE = KEPT / "steps_dataset_grid"
#: The listeners whose ears are fitted to hard scans: registered or placed, with the layer or without; and the placed,
#: layered listener whose hard scans are completed by the truth where they were blind (hard_oracle_placed, and
#: hard_blind_oracle_placed with the scans' heights kept where they saw); the
#: placed listeners with another layer (hard_<variant>_placed) and on further draws of the hard scans (..._draw<N>).
HARD_KINDS = ("hard", "hard_ppm", "hard_placed", "hard_ppm_placed", "hard_oracle_placed", "hard_noise_placed",
              "hard_supple_placed", "hard_points_placed", "hard_placed_draw1",
              "hard_points_placed_draw1", "hard_placed_draw2", "hard_points_placed_draw2",
              "hard_oracle_placed_draw1", "hard_blind_oracle_placed")
#: The oracles of the placed hard listener (hard_ear_scans' ``oracle``) and the part of a listener's name they add.
ORACLES = {"": "", "completed": "_oracle", "blind": "_blind_oracle"}
#: The layer's settings (ppm/data/personal_detail.yaml names) of the placed hard listeners hard_<variant>_placed whose
#: layer differs from the packaged one.
LAYER_VARIANTS = {"noise": {"noise_stiffness_factor": 1.0},
                  "supple": {"stiffness_mm2": [10.0, 2.0, 0.5, 0.1, 0.03]},
                  "points": {"stiffness_mm2": [10.0, 2.0, 0.5, 0.1, 0.03], "forward_weight": 0.3}}
#: The clean head scan's listeners whose layer is laid with a variant of LAYER_VARIANTS (new_<variant>): whether a
#: variant that brings the hard listener nearer keeps the clean one where it is.
CLEAN_VARIANT_KINDS = tuple(f"new_{variant}" for variant in LAYER_VARIANTS)
DATASET_SOFA = "hrir_mesh2hrtf_48k.sofa"
#: Keys of the kept JSON that the report works out itself after the carry (from fresh or carried figures): never
#: carried.
DERIVED_AFTER_CARRY = ("carried_from_kept", "unseen_share_of_hard_placed_gap", "hard_placed_draws_mean",
                       "hard_points_placed_draws_mean", "hard_oracle_placed_draws_mean",
                       "unseen_share_of_hard_placed_gap_draws", "unseen_parts_share_of_hard_placed_gap")


def evaluation_hard_scan() -> dict:
    """The evaluation's hard-scan recipe (config/config.yaml evaluation.hard_scan: level and seed): the left ear's
    hard scan is the evaluation's own."""
    import yaml  # noqa: PLC0415

    return yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))["evaluation"]["hard_scan"]


def posed_head(subject: str, seed: int) -> tuple[Path, np.ndarray]:
    """The subject's both-ear head turned at random, moved by up to 300 mm and written in cm; the 4x4 pose (mm)."""
    import trimesh  # noqa: PLC0415
    from scipy.spatial.transform import Rotation  # noqa: PLC0415

    from listener.dataset_heads import both_ears_head  # noqa: PLC0415

    rng = np.random.default_rng(seed)
    pose = np.eye(4)
    pose[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    pose[:3, 3] = rng.uniform(-300.0, 300.0, 3)
    path = WORK / f"{subject}_head_cm.ply"
    if not path.is_file():
        head = both_ears_head(SONICOM / subject)
        WORK.mkdir(parents=True, exist_ok=True)
        vertices = (np.asarray(head.vertices) @ pose[:3, :3].T + pose[:3, 3]) / 10.0
        trimesh.Trimesh(vertices, head.faces, process=False).export(path)
    return path, pose


def hard_scan_mm(subject: str, side: str, draw: int = 0) -> "trimesh.Trimesh":
    """The ``side`` ear's fixed hard scan (mm, head frame): the left ear is the evaluation's own hard scan
    (:func:`evaluation_hard_scan`, the seed mixed with the subject's name, evaluation/sonicom/hard_scans/), the right
    ear the same recipe on the mirrored right crop with the seed mixed with "<subject>_right"
    (stitching.both_ears.right_ear_scan_as_left), mirrored back. ``draw`` N > 0: another draw of the same recipe,
    its seed the recipe's plus N (how far the hard listener's figures move with the scans' noise and holes)."""
    from ppm.align.defects import hard_scan_of  # noqa: PLC0415
    from stitching.both_ears import mirror_left_right, right_ear_scan_as_left  # noqa: PLC0415

    recipe = evaluation_hard_scan()
    crop = SONICOM / subject / f"pinna_{side}_crop.ply"
    seed = int(recipe["seed"]) + int(draw)
    if side == "left":
        return hard_scan_of(crop, subject, recipe["level"], seed)[0]
    return mirror_left_right(right_ear_scan_as_left(crop, subject, recipe["level"], seed))


def hard_ear_scans(subject: str, seed: int, pose: np.ndarray, oracle: str = "", draw: int = 0) -> dict[str, Path]:
    """Both ears of the subject scanned at the ``hard`` level of ppm/data/scan_defects.yaml (occlusion holes, 2 mm
    sampling, 0.5 mm noise, outliers, spikes, a partial crop), each its own fixed draw (:func:`hard_scan_mm`); with
    ``oracle`` "completed" each completed where it was blind by the clean crop
    (reporting.stitched_region.completed_where_blind: the truth moved to its closest point on the scan where it saw),
    with "blind" the same with the truth moved along its normals onto the scan, so that the seen parts keep the scan's
    heights (reporting.stitched_region.heights_where_seen);
    ``draw`` N > 0: another draw (:func:`hard_scan_mm`). Posed and written in centimetres as the head is; returns
    side -> file."""
    import trimesh  # noqa: PLC0415

    from core.atomic import atomic_path  # noqa: PLC0415
    from reporting.stitched_region import completed_where_blind, heights_where_seen  # noqa: PLC0415

    paths = {}
    for side in ("left", "right"):
        path = WORK / f"{subject}_hard{ORACLES[oracle]}{f'_draw{draw}' if draw else ''}_{side}_ear_cm.ply"
        paths[side] = path
        if path.is_file():
            continue
        scan = hard_scan_mm(subject, side, draw)
        if oracle:
            crop = trimesh.load(SONICOM / subject / f"pinna_{side}_crop.ply", process=False, force="mesh")
            if oracle == "completed":
                scan = completed_where_blind(scan, crop)
            else:
                scan, placing = heights_where_seen(scan, crop)
                print(f"{path.name}: the seen vertices of the crop placed on the scan: {placing}", flush=True)
        posed = (np.asarray(scan.vertices) @ pose[:3, :3].T + pose[:3, 3]) / 10.0
        with atomic_path(path) as temporary:  # makes WORK too
            trimesh.Trimesh(posed, scan.faces, process=False).export(temporary, file_type="ply")
    return paths


def snakemake(args: list[str]) -> None:
    command = [sys.executable, "-m", "snakemake", *args]
    print("$", " ".join(command), flush=True)
    subprocess.run(command, cwd=ROOT, check=True)


def listener_kind(hard: bool = False, layer: bool = True, placed: bool = False, oracle: str = "",
                  variant: str | None = None, draw: int = 0) -> str:
    """Which of the subject's listeners (named <subject>_<kind>): new (the clean head scan), hard (hard ear scans,
    registered onto the head's ears), hard_ppm (the same, no personal-detail layer), hard_placed (the same hard ear
    scans placed by the head's frame: they share the head scan's coordinates, as the ear regions of one scan do),
    hard_ppm_placed (the placed scans, no layer), hard_oracle_placed (the placed, layered listener whose hard scans
    are completed by the clean crop where they were blind), hard_<variant>_placed (the placed, layered listener whose
    layer is laid with :data:`LAYER_VARIANTS` [variant]: noise, ended at the scan's noise; supple, a stage further;
    points, the supple end led by the scan's points more than by its surface), hard[_<variant>]_placed_draw<N> (the
    placed, layered listener on another draw of the hard scans), hard_oracle_placed_draw<N> (that draw completed by
    the clean crop where it was blind), hard_blind_oracle_placed (the hard scans completed where they were blind, their
    own heights kept where they saw), new_<variant> (the clean head scan, its layer laid with
    :data:`LAYER_VARIANTS` [variant])."""
    if not hard:
        return f"new_{variant}" if variant else "new"
    if draw:
        return f"hard{ORACLES[oracle] or ('_' + variant if variant else '')}_placed_draw{draw}"
    if oracle:
        return f"hard{ORACLES[oracle]}_placed"
    if variant:
        return f"hard_{variant}_placed"
    return ("hard" if layer else "hard_ppm") + ("_placed" if placed else "")


def run(subject: str, seed: int, cores: int, targets: list[str] | None = None, hard: bool = False,
        layer: bool = True, placed: bool = False, oracle: str = "", variant: str | None = None,
        draw: int = 0) -> None:
    """The template without the subject, then the listener's whole run (NumCalc), or only ``targets``; with
    ``hard`` the listener whose ear scans are the hard ones (<subject>_hard; without ``layer`` <subject>_hard_ppm;
    with ``placed`` <subject>_hard_placed, the ear scans placed by the head's frame; with ``oracle`` "completed"
    <subject>_hard_oracle_placed, "blind" <subject>_hard_blind_oracle_placed)."""
    config = write_config(subject, seed, hard, layer, placed, oracle, variant, draw)
    snakemake(["--cores", str(cores), "--configfile", str(config.relative_to(ROOT)), "--rerun-triggers", "mtime",
               "--rerun-incomplete",
               *(["--nolock"] if hard or variant else []), *(["--", *targets] if targets else [])])


def write_config(subject: str, seed: int, hard: bool = False, layer: bool = True, placed: bool = False,
                 oracle: str = "", variant: str | None = None, draw: int = 0) -> Path:
    """The run's config (results/new_listener/config.yaml; config_hard.yaml for the listener <subject>_hard, whose
    ears are fitted to their hard scans, given as the listener's separate ear scans, and whose reference is
    <subject>_new's head as scanned; config_hard_ppm.yaml for the same without the layer; config_hard_placed.yaml for
    the hard ear scans placed by the head's frame, ear_scan_frame: head; config_hard_oracle_placed.yaml for the placed
    scans completed by the truth where they were blind; config_hard_blind_oracle_placed.yaml for the placed scans with
    their heights kept where they saw; config_hard_<variant>_placed.yaml for the placed scans, the
    layer laid with LAYER_VARIANTS[variant]; config_hard_placed_draw<N>.yaml for another draw of the hard scans,
    placed; config_new_<variant>.yaml for the clean head scan with a layer variant, judged against <subject>_new's head
    as scanned), the template without the subject built first."""
    head, pose = posed_head(subject, seed)
    template = f"results/templates/without_{subject}/template_left.ply"
    if not (ROOT / template).is_file():
        snakemake(["--cores", "1", "--config", f"data_root={SONICOM}", "--", template])
    kind = listener_kind(hard, layer, placed, oracle, variant, draw)
    listener = {"name": f"{subject}_{kind}", "head": str(head.relative_to(ROOT))}
    if hard:
        ears = hard_ear_scans(subject, seed, pose, oracle, draw)
        listener.update({f"{side}_ear": str(path.relative_to(ROOT)) for side, path in ears.items()})
        if placed or oracle or variant or draw:
            # written with the head's pose and unit: in the head scan's own coordinates
            listener["ear_scan_frame"] = "head"
    config = WORK / ("config.yaml" if kind == "new" else f"config_{kind}.yaml")
    config.write_text(json.dumps({
        "listeners": [listener],
        "listener": {"template": str(Path(template).parent), "comparison_sets": [], "personal_detail": layer,
                     "scanned_head": kind == "new", "dataset_grid": str(SONICOM / subject / DATASET_SOFA),
                     **({"personal_detail_settings": LAYER_VARIANTS[variant]} if variant else {})},
        "hrtf": {"enabled": True, "solver": "numcalc", "frequencies_hz": "evaluation",
                 "step_store": str(STORE.relative_to(ROOT))},
    }, indent=1))
    return config


class StoreWork(NamedTuple):
    """What the steps kept under one head's folder of the step store cost (:func:`store_work`)."""

    cpu_hours: float
    iterations: int  # NumCalc iterations, all attempts: the work, whatever else the machine ran
    steps: int  # steps kept
    ears: set[str]  # the sources (ears) they belong to


def store_work(folder: Path) -> StoreWork:
    """NumCalc CPU hours, iterations (all attempts) and count of the steps kept under ``folder``, and their sources.
    The iterations are the work; CPU seconds per iteration depend on what else the machine runs (1.7-3.1 s on this
    2-core machine for heads of the same size), so the CPU hours of solves made beside other work are not the
    head's alone."""
    from mesh2hrtf_io.step_store import solve_cpu_seconds  # noqa: PLC0415

    cpu, iterations, steps, ears = 0.0, 0, 0, set()
    for stored in sorted(folder.rglob("step_*.npz")):
        with np.load(stored) as kept:
            status = json.loads(str(kept["status_json"]))
        cpu += solve_cpu_seconds(status)
        iterations += sum(int(attempt.get("iterations", 0)) for attempt in status.get("attempts", []))
        steps += 1
        ears.add(stored.parent.name)
    return StoreWork(cpu / 3600.0, iterations, steps, ears)


def dataset_line(personal_hrir: Path, dataset_sofa: Path) -> dict:
    """The second line: the dataset's HRIRs (rebuilt at the solved frequencies) are the template, S at 8 % QE on
    them, the personal set heard with them on the directions both have; each ear alone (the other from the
    dataset). It includes this pipeline's solve against the dataset's, which the paper's protocol takes out."""
    import sofar  # noqa: PLC0415

    from amt_bridge.hrtf_set import read_hrtf_set, resampled_at  # noqa: PLC0415
    from reporting.paper_protocol import both_ears_protocol  # noqa: PLC0415

    frequencies = np.asarray(sofar.read_sofa(str(personal_hrir.with_name("HRTF.sofa")), verify=False).N)
    dataset = resampled_at(read_hrtf_set(dataset_sofa), frequencies)
    return both_ears_protocol(dataset, read_hrtf_set(personal_hrir), tolerance_deg=2.0)


def paper_line(personal_hrir: Path, scanned_hrir: Path, dataset_sofa: Path) -> dict:
    """The paper's protocol: the listener's head as scanned (both ears unchanged, solved as the personal head) is
    reference and template, both sets on the dataset's directions (reporting.paper_protocol.both_ears_protocol)."""
    from amt_bridge.hrtf_set import read_hrtf_set  # noqa: PLC0415
    from reporting.paper_protocol import both_ears_protocol  # noqa: PLC0415

    return both_ears_protocol(read_hrtf_set(scanned_hrir), read_hrtf_set(personal_hrir), read_hrtf_set(dataset_sofa))


def ears_gap(judged: dict) -> dict:
    """Why both ears cost more than the two ears alone added: per sagittal plane (deg lateral, + = left), the
    QE (pp) with the left ear alone personal, the right alone, both, and both minus the sum of the two alone."""
    rows = {}
    for index, plane in enumerate(judged["reference"]["planes"]):
        deltas = {key: judged[key]["planes"][index]["qe_percent"] - plane["qe_percent"]
                  for key in ("left", "right", "both")}
        rows[f"{plane['lateral_deg']:+.0f}"] = {**{k: round(v, 3) for k, v in deltas.items()},
                                                "excess": round(deltas["both"] - deltas["left"] - deltas["right"], 3)}
    return rows


def other_person_gap(subject: str) -> dict:
    """:func:`ears_gap` of another SONICOM subject's dataset set heard with ``subject``'s (both from the dataset, no
    solve), and the QE/PE deltas of both ears and each alone."""
    from amt_bridge.hrtf_set import read_hrtf_set  # noqa: PLC0415
    from reporting.paper_protocol import both_ears_protocol  # noqa: PLC0415

    other = next(p.name for p in sorted(SONICOM.iterdir()) if p.name != subject and (p / DATASET_SOFA).is_file())
    own = read_hrtf_set(SONICOM / subject / DATASET_SOFA)
    judged = both_ears_protocol(own, read_hrtf_set(SONICOM / other / DATASET_SOFA), own)
    return {"other": other, **{key: round(judged[key]["delta_qe_pp"], 3) for key in ("both", "left", "right")},
            "planes": ears_gap(judged)}


def fit_figures(base: Path, pose: np.ndarray) -> dict:
    """Frame, fits and remesh of the run so far (what exists of them)."""
    from listener.units import UNIT_MM  # noqa: PLC0415

    summary: dict = {}
    if (base / "prepared" / "frame.json").is_file():
        frame = json.loads((base / "prepared" / "frame.json").read_text())
        composite = np.asarray(frame["matrix"]) @ np.diag([1.0 / UNIT_MM[frame["unit"]]] * 3 + [1.0]) @ pose
        axis = composite[1, :3] / np.linalg.norm(composite[1, :3])
        summary.update(frame_axis_error_deg=round(float(np.degrees(np.arccos(np.clip(axis[1], -1, 1)))), 3),
                       frame_origin_error_mm=round(float(np.linalg.norm(composite[:3, 3])), 2))
    summary.update(ear_figures(base))
    for name, key in (("remesh", "head_triangles"), ("scanned", "scanned_head_triangles")):
        if (base / name / "validation.json").is_file():
            validation = json.loads((base / name / "validation.json").read_text())
            summary[key] = validation["n_triangles"]
            if name == "remesh":
                summary.update(left_pinna_edge_median_mm=round(validation["pinna_edge_mm"]["median"], 3),
                               right_pinna_edge_median_mm=round(validation["right_pinna_edge_mm"]["median"], 3))
    return summary


def ear_figures(base: Path, prefix: str = "") -> dict:
    """Of a listener's run folder ``base``, what exists of: each ear's fit, median scan -> PPM (mm,
    ``<prefix><side>_fit_median_mm``), and the share of its whole pinna the scan saw (``<prefix>coverage_<side>``)."""
    figures = {}
    for side in ("left", "right"):
        fit = base / "align" / side / "summary.json"
        if fit.is_file():
            figures[f"{prefix}{side}_fit_median_mm"] = json.loads(fit.read_text())["distance_target_to_ppm"]["median_mm"]
    if (base / "coverage.json").is_file():
        ears = json.loads((base / "coverage.json").read_text())["ears"]
        for side in ("left", "right"):
            figures[f"{prefix}coverage_{side}"] = round(next(r["seen_share"] for r in ears[side]
                                                             if r["region"] == "whole pinna"), 4)
    return figures


def ears_to_scanned(personal_head: Path, scanned_head: Path) -> dict:
    """How far each ear of a personal head lies from the head as scanned (mm, project frame): over both meshes'
    vertices in the ear's crop box (listener.ears: |x| < 50, |z| < 55, |y| > 50 mm), each to the other's surface, the
    median, p95 and share beyond 0.5 mm, by side. The clean listener's ears lie within a few hundredths (median)."""
    import trimesh  # noqa: PLC0415

    from listener.ears import in_crop_box  # noqa: PLC0415

    personal = trimesh.load(personal_head, process=False, force="mesh")
    scanned = trimesh.load(scanned_head, process=False, force="mesh")

    def in_box(mesh: trimesh.Trimesh, side: str) -> np.ndarray:
        return np.asarray(mesh.vertices)[in_crop_box(mesh.vertices, side)]

    out = {}
    for side in ("left", "right"):
        distance = np.concatenate([trimesh.proximity.closest_point(scanned, in_box(personal, side))[1],
                                   trimesh.proximity.closest_point(personal, in_box(scanned, side))[1]])
        out[side] = {"median_mm": round(float(np.median(distance)), 3),
                     "p95_mm": round(float(np.percentile(distance, 95)), 3),
                     "share_over_0_5mm": round(float(np.mean(distance > 0.5)), 3)}
    return out


def gap_share(summary: dict, oracle: str, layered: str) -> dict | None:
    """The share of listener ``layered``'s both-ear ΔQE and ΔPE that listener ``oracle`` takes away (1 - oracle /
    layered), or None while either is unjudged."""
    if summary.get(f"{oracle}_paper_delta_qe_pp") is None or not summary.get(f"{layered}_paper_delta_qe_pp"):
        return None
    return {quantity: round(1.0 - summary[f"{oracle}_paper_delta_{quantity}"]
                            / summary[f"{layered}_paper_delta_{quantity}"], 3) for quantity in ("qe_pp", "pe_deg")}


def report(subject: str, seed: int) -> dict:
    """The figures of a (finished or partial) run."""
    _, pose = posed_head(subject, seed)
    base = ROOT / "results" / "listeners" / f"{subject}_new"
    summary: dict = {key: None for key in ("paper_delta_qe_pp", "paper_delta_pe_deg", "paper_left_delta_qe_pp",
                                           "paper_right_delta_qe_pp", "hard_paper_delta_qe_pp",
                                           "hard_paper_delta_pe_deg", "hard_ppm_paper_delta_qe_pp",
                                           "hard_ppm_paper_delta_pe_deg", "coverage_left", "coverage_right",
                                           "directions_compared", "delta_qe_pp", "delta_pe_deg")}
    summary.update(fit_figures(base, pose))
    personal_work = store_work(STORE / "listeners" / f"{subject}_new" / "personal")
    reference_work = store_work(STORE / "listeners" / f"{subject}_new" / "scanned")
    personal, scanned = (base / "hrtf" / variant / "HRIR.sofa" for variant in ("personal", "scanned"))
    dataset = SONICOM / subject / DATASET_SOFA
    summary.update(ears_solved=len(personal_work.ears), cpu_hours=round(personal_work.cpu_hours, 3),  # stored ears
                   numcalc_iterations=personal_work.iterations,
                   reference_cpu_hours=round(reference_work.cpu_hours, 3), personal_detail=True)
    if personal.is_file():
        second = dataset_line(personal, dataset)
        summary.update(delta_qe_pp=round(second["both"]["delta_qe_pp"], 3),
                       delta_pe_deg=round(second["both"]["delta_pe_deg"], 3),
                       dataset_directions_compared=second["directions"])
        for side in ("left", "right"):
            summary[f"{side}_ear_only_delta_qe_pp"] = round(second[side]["delta_qe_pp"], 3)
            summary[f"{side}_ear_only_delta_pe_deg"] = round(second[side]["delta_pe_deg"], 3)
    if scanned.is_file():
        # this pipeline's solve of the head as scanned against the dataset's own HRIRs: what the second line
        # carries besides the ears
        solve = dataset_line(scanned, dataset)
        summary.update(scanned_vs_dataset_delta_qe_pp=round(solve["both"]["delta_qe_pp"], 3),
                       scanned_vs_dataset_delta_pe_deg=round(solve["both"]["delta_pe_deg"], 3))
    if personal.is_file() and scanned.is_file():
        paper = paper_line(personal, scanned, dataset)
        summary.update(paper_delta_qe_pp=round(paper["both"]["delta_qe_pp"], 3),
                       paper_delta_pe_deg=round(paper["both"]["delta_pe_deg"], 3),
                       paper_left_delta_qe_pp=round(paper["left"]["delta_qe_pp"], 3),
                       paper_right_delta_qe_pp=round(paper["right"]["delta_qe_pp"], 3),
                       paper_left_delta_pe_deg=round(paper["left"]["delta_pe_deg"], 3),
                       paper_right_delta_pe_deg=round(paper["right"]["delta_pe_deg"], 3),
                       paper_sensitivity_db=round(paper["sensitivity_db"], 4),
                       paper_reference_qe_percent=round(paper["reference"]["qe_percent"], 3),
                       directions_compared=paper["directions"], paper_ears_gap_by_plane=ears_gap(paper))
    # the same split for another person's whole set (a dataset subject's HRIRs heard with this subject's): whether
    # both ears together costing more than the two alone added is the model's, not the pipeline's
    summary["other_person_ears_gap_by_plane"] = other_person_gap(subject)
    # the hard listener, with the layer (hard_) and without it (hard_ppm_), judged against the same head as scanned
    scanned_head = STORE / "listeners" / f"{subject}_new" / "scanned" / "head.ply"
    for kind in ("new", *HARD_KINDS, *CLEAN_VARIANT_KINDS):
        # each personal head's ears against the head as scanned (the stored, solved heads)
        personal_head = STORE / "listeners" / f"{subject}_{kind}" / "personal" / "head.ply"
        if personal_head.is_file() and scanned_head.is_file():
            summary[f"{'' if kind == 'new' else kind + '_'}ears_to_scanned"] = ears_to_scanned(personal_head,
                                                                                              scanned_head)
    for kind in (*HARD_KINDS, *CLEAN_VARIANT_KINDS):
        base_kind = ROOT / "results" / "listeners" / f"{subject}_{kind}"
        kind_work = store_work(STORE / "listeners" / f"{subject}_{kind}" / "personal")
        summary.update(ear_figures(base_kind, f"{kind}_"))
        solved = base_kind / "hrtf" / "personal" / "HRIR.sofa"
        # figures of a finished solve only (the collected set, or as many steps kept as the clean listener's, is its
        # sign); a solve under way gives its steps so far
        complete = solved.is_file() or kind_work.steps == personal_work.steps
        summary[f"{kind}_cpu_hours"] = round(kind_work.cpu_hours, 3) if complete else None
        summary[f"{kind}_numcalc_iterations"] = kind_work.iterations if complete else None
        summary[f"{kind}_steps_kept"] = kind_work.steps
        if solved.is_file() and scanned.is_file():
            judged = paper_line(solved, scanned, dataset)
            summary.update({f"{kind}_paper_delta_qe_pp": round(judged["both"]["delta_qe_pp"], 3),
                            f"{kind}_paper_delta_pe_deg": round(judged["both"]["delta_pe_deg"], 3),
                            f"{kind}_paper_left_delta_qe_pp": round(judged["left"]["delta_qe_pp"], 3),
                            f"{kind}_paper_right_delta_qe_pp": round(judged["right"]["delta_qe_pp"], 3),
                            f"{kind}_paper_ears_gap_by_plane": ears_gap(judged)})
    for layered, bare, key in (("hard", "hard_ppm", "hard_layer_nearer"),
                               ("hard_placed", "hard_ppm_placed", "hard_placed_layer_nearer")):
        if summary.get(f"{bare}_paper_delta_qe_pp") is not None and summary.get(f"{layered}_paper_delta_qe_pp") is not None:
            # the layer brings the hard listener nearer its own ears when both |delta QE| and |delta PE| are smaller
            summary[key] = bool(
                abs(summary[f"{layered}_paper_delta_qe_pp"]) < abs(summary[f"{bare}_paper_delta_qe_pp"])
                and abs(summary[f"{layered}_paper_delta_pe_deg"]) < abs(summary[f"{bare}_paper_delta_pe_deg"]))
    kept_file = KEPT / f"{subject}.json"
    if kept_file.is_file():
        # figures of a run folder this machine does not have (results/ is not committed: the fits, the frame, the
        # remesh of an earlier run) are carried from the kept JSON and named, not dropped
        kept = json.loads(kept_file.read_text())
        carried = sorted(key for key in kept if summary.get(key) is None and kept[key] is not None
                         and key not in DERIVED_AFTER_CARRY)
        summary.update({key: kept[key] for key in carried})
        if carried:
            summary["carried_from_kept"] = carried
            print(f"carried from the kept {kept_file.name} (their run folders are not on this machine): "
                  f"{', '.join(carried)}", flush=True)
    # after the carry: on a fresh clone both figures may come from the kept JSON
    # what completing the hard scans where they were blind takes off the placed hard listener's gap (share of it):
    # the closest-point oracle on each draw solved, and the oracle that keeps the scans' heights where they saw
    shares = {"unseen_share_of_hard_placed_gap": gap_share(summary, "hard_oracle_placed", "hard_placed"),
              "unseen_parts_share_of_hard_placed_gap": gap_share(summary, "hard_blind_oracle_placed", "hard_placed")}
    summary.update({key: share for key, share in shares.items() if share})
    by_draw = {kind.removeprefix("hard_oracle_placed_"): gap_share(summary, kind, kind.replace("_oracle", ""))
               for kind in HARD_KINDS if kind.startswith("hard_oracle_placed_draw")}
    if any(by_draw.values()):
        summary["unseen_share_of_hard_placed_gap_draws"] = {draw: share for draw, share in by_draw.items() if share}
    for layer in ("hard_placed", "hard_points_placed", "hard_oracle_placed"):
        # a layer setting over the hard scans' draws: the first draw and every further one solved
        # (<layer>_draw<N>); one draw moves the figures by as much as a setting does
        draws = [kind for kind in HARD_KINDS if kind == layer or kind.startswith(f"{layer}_draw")]
        judged = [kind for kind in draws if summary.get(f"{kind}_paper_delta_qe_pp") is not None]
        if len(judged) > 1:
            summary[f"{layer}_draws_mean"] = {
                "draws": len(judged),
                **{f"paper_delta_{quantity}": round(float(np.mean(
                    [summary[f"{kind}_paper_delta_{quantity}"] for kind in judged])), 3)
                   for quantity in ("qe_pp", "pe_deg")}}
            print(f"{layer} over {len(judged)} draws of the hard scans: "
                  + ", ".join(f"{summary[kind + '_paper_delta_qe_pp']:+.2f} pp / "
                              f"{summary[kind + '_paper_delta_pe_deg']:+.2f} deg" for kind in judged)
                  + f"; mean {summary[layer + '_draws_mean']['paper_delta_qe_pp']:+.2f} pp / "
                  f"{summary[layer + '_draws_mean']['paper_delta_pe_deg']:+.2f} deg", flush=True)
    print(f"{subject} as a new listener: {json.dumps({k: v for k, v in summary.items() if not isinstance(v, dict)})}",
          flush=True)
    if summary.get("paper_delta_qe_pp") is not None:
        print(f"paper's protocol (template: the head as scanned, {summary['directions_compared']} dataset directions, "
              f"S {summary['paper_sensitivity_db']} dB): both ears {summary['paper_delta_qe_pp']:+.2f} pp / "
              f"{summary['paper_delta_pe_deg']:+.2f} deg; left ear alone {summary['paper_left_delta_qe_pp']:+.2f} pp, "
              f"right alone {summary['paper_right_delta_qe_pp']:+.2f} pp", flush=True)
        for plane, row in summary["paper_ears_gap_by_plane"].items():
            print(f"  plane {plane} deg: left alone {row['left']:+.2f}, right alone {row['right']:+.2f}, both "
                  f"{row['both']:+.2f} pp (both minus the sum {row['excess']:+.2f})", flush=True)
    from core.atomic import write_text_atomic  # noqa: PLC0415

    KEPT.mkdir(parents=True, exist_ok=True)
    write_text_atomic(kept_file, json.dumps(summary, indent=1) + "\n")
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument("--report-only", action="store_true", help="judge what has been run so far")
    parser.add_argument("--hard", action="store_true",
                        help="run the listener <subject>_hard (both ears fitted to hard scans) instead")
    parser.add_argument("--no-layer", action="store_true",
                        help="with --hard: the listener <subject>_hard_ppm, the same hard ear scans without the "
                        "personal-detail layer")
    parser.add_argument("--placed", action="store_true",
                        help="with --hard: the listener <subject>_hard_placed (with --no-layer "
                        "<subject>_hard_ppm_placed), the same hard ear scans placed by the head's frame (they share the "
                        "head scan's coordinates) instead of registered")
    parser.add_argument("--oracle", action="store_true",
                        help="with --hard: the listener <subject>_hard_oracle_placed, the placed hard ear scans "
                        "completed by the clean crop where they were blind (how much of the hard listener's gap the "
                        "unseen parts cost)")
    parser.add_argument("--blind-oracle", action="store_true",
                        help="with --hard: the listener <subject>_hard_blind_oracle_placed, the placed hard ear scans "
                        "completed by the clean crop where they were blind, their own heights kept where they saw (near "
                        "what a perfect guess of the unseen parts alone is worth)")
    parser.add_argument("--noise-floor", action="store_true",
                        help="with --hard: the listener <subject>_hard_noise_placed, the placed hard ear scans with "
                        "the layer's stiffness schedule ended at their own noise (noise_stiffness_factor 1)")
    parser.add_argument("--supple-end", action="store_true",
                        help="with --hard: the listener <subject>_hard_supple_placed, the placed hard ear scans with "
                        "the layer's stiffness schedule taken a stage further, to 0.03 mm²")
    parser.add_argument("--layer-variant", choices=sorted(LAYER_VARIANTS), default=None,
                        help="the listener <subject>_new_<NAME> (the clean head scan), with --hard "
                        "<subject>_hard_<NAME>_placed (the placed hard ear scans), its layer laid with "
                        "LAYER_VARIANTS[NAME] (--noise-floor is noise, --supple-end supple)")
    parser.add_argument("--draw", type=int, default=0,
                        help="with --hard --placed (or --oracle, or --layer-variant NAME): the listener "
                        "<subject>_hard[_oracle|_NAME]_placed_draw<N>, the same recipe's hard ear scans drawn with the "
                        "evaluation's seed plus N (how far the figures move with the draw)")
    parser.add_argument("--until", default=None, help="run only up to this output of the listener (e.g. "
                        "remesh/validation.json: fits, stitch and remesh without the solve)")
    args = parser.parse_args()
    if not args.report_only:
        if args.no_layer and not args.hard:
            parser.error("--no-layer goes with --hard (the clean listener's layerless head is kept in steps/)")
        if args.oracle and args.blind_oracle:
            parser.error("--oracle or --blind-oracle: one of them")
        oracle = "completed" if args.oracle else "blind" if args.blind_oracle else ""
        if (args.placed or oracle) and not args.hard:
            parser.error("--placed, --oracle and --blind-oracle go with --hard")
        if oracle and args.no_layer:
            parser.error("--oracle and --blind-oracle are the placed listener with the layer")
        chosen = [name for name in ("noise" if args.noise_floor else None, "supple" if args.supple_end else None,
                                    args.layer_variant) if name]
        variant = chosen[0] if chosen else None
        if variant and (args.no_layer or oracle or len(chosen) > 1):
            parser.error("--noise-floor, --supple-end or --layer-variant (one) goes with the layer, without an oracle "
                         "(with --hard it is placed)")
        if args.draw and (args.draw < 0 or not (args.hard and (args.placed or args.oracle or variant))
                          or args.no_layer or args.blind_oracle):
            parser.error("--draw N (N > 0) goes with --hard --placed (or --oracle, or a layer variant), with the layer")
        kind = listener_kind(args.hard, not args.no_layer, args.placed, oracle, variant, args.draw)
        name = f"{args.subject}_{kind}"
        run(args.subject, args.seed, args.cores, [f"results/listeners/{name}/{args.until}"] if args.until else None,
            args.hard, not args.no_layer, args.placed, oracle, variant, args.draw)
    print(json.dumps(report(args.subject, args.seed)))


if __name__ == "__main__":
    main()
