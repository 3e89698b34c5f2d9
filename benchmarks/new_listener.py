"""A SONICOM subject treated as a new listener (issue 42): its head, with both ears as finely resolved as the
dataset has them (listener.dataset_heads.both_ears_head), turned at random and written in centimetres, no separate
ear scans, the PPM template built without it; through the listener workflow end to end with NumCalc (both ears,
a mesh per frequency band), then judged:

- the head frame found against the dataset's frame (the pose applied is known): axis and origin errors;
- both PPM fits: median distance from the ear crop to the fitted PPM (mm);
- NumCalc CPU hours of both ears (the step statuses kept in the step store);
- QE/PE of the personal set by the evaluation's protocol: the dataset's reference HRIRs are the template, S is
  calibrated so that they give 8 % QE heard through themselves, and the personal set is heard with them.

The steps are kept in benchmarks/results/new_listener/steps as they finish, so that a run stopped on the way (or a
fresh clone) continues from them. The posed head and the run's outputs stay in results/new_listener/ and
results/listeners/ (not committed: the head is the dataset's).

Run: .venv/bin/python benchmarks/new_listener.py [--subject P143] [--seed 7] [--cores 2] [--report-only]
Last line: JSON with frame_axis_error_deg, frame_origin_error_mm, left_fit_median_mm, right_fit_median_mm,
ears_solved, cpu_hours, delta_qe_pp, delta_pe_deg (null where the solve has not finished), the directions the two
sets share, and each ear alone (the other ear from the dataset's set): <side>_ear_only_delta_qe_pp / _pe_deg.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SONICOM = ROOT.parent / "shared" / "data" / "sonicom"
KEPT = ROOT / "benchmarks" / "results" / "new_listener"
WORK = ROOT / "results" / "new_listener"


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


def snakemake(args: list[str]) -> None:
    command = [sys.executable, "-m", "snakemake", *args]
    print("$", " ".join(command), flush=True)
    subprocess.run(command, cwd=ROOT, check=True)


def run(subject: str, seed: int, cores: int) -> None:
    """The template without the subject, then the listener's whole run (NumCalc)."""
    head, _ = posed_head(subject, seed)
    template = f"results/templates/without_{subject}/template_left.ply"
    if not (ROOT / template).is_file():
        snakemake(["--cores", "1", "--config", f"data_root={SONICOM}", "--", template])
    config = WORK / "config.yaml"
    config.write_text(json.dumps({
        "listeners": [{"name": f"{subject}_new", "head": str(head.relative_to(ROOT))}],
        "listener": {"template": str(Path(template).parent), "comparison_sets": []},
        "hrtf": {"enabled": True, "solver": "numcalc", "frequencies_hz": "evaluation",
                 "step_store": str(KEPT.relative_to(ROOT) / "steps")},
    }, indent=1))
    snakemake(["--cores", str(cores), "--configfile", str(config.relative_to(ROOT)), "--rerun-triggers", "mtime"])


def report(subject: str, seed: int) -> dict:
    """The figures of a (finished or partial) run."""
    from listener.units import UNIT_MM  # noqa: PLC0415
    from mesh2hrtf_io.step_store import solve_cpu_seconds  # noqa: PLC0415

    _, pose = posed_head(subject, seed)
    base = ROOT / "results" / "listeners" / f"{subject}_new"
    frame = json.loads((base / "prepared" / "frame.json").read_text())
    matrix = np.asarray(frame["matrix"])
    composite = matrix @ np.diag([1.0 / UNIT_MM[frame["unit"]]] * 3 + [1.0]) @ pose
    axis = composite[1, :3] / np.linalg.norm(composite[1, :3])
    summary = {"frame_axis_error_deg": round(float(np.degrees(np.arccos(np.clip(axis[1], -1, 1)))), 3),
               "frame_origin_error_mm": round(float(np.linalg.norm(composite[:3, 3])), 2)}
    for side in ("left", "right"):
        fit = json.loads((base / "align" / side / "summary.json").read_text())
        summary[f"{side}_fit_median_mm"] = fit["distance_target_to_ppm"]["median_mm"]
    validation = json.loads((base / "remesh" / "validation.json").read_text())
    summary.update(head_triangles=validation["n_triangles"],
                   left_pinna_edge_median_mm=round(validation["pinna_edge_mm"]["median"], 3),
                   right_pinna_edge_median_mm=round(validation["right_pinna_edge_mm"]["median"], 3))
    cpu, ears = 0.0, set()
    for stored in sorted((KEPT / "steps").rglob("step_*.npz")):
        with np.load(stored) as kept:
            cpu += solve_cpu_seconds(json.loads(str(kept["status_json"])))
        ears.add(stored.parent.name)
    hrir = base / "hrtf" / "personal" / "HRIR.sofa"
    summary.update(ears_solved=len(ears) if hrir.is_file() else 0, cpu_hours=round(cpu / 3600.0, 3),
                   delta_qe_pp=None, delta_pe_deg=None)
    if hrir.is_file():
        import sofar  # noqa: PLC0415

        from amt_bridge.hrtf_set import on_common_directions, read_hrtf_set, resampled_at  # noqa: PLC0415
        from amt_bridge.model import LocalisationModel  # noqa: PLC0415

        # the evaluation's protocol: the dataset's HRIRs, rebuilt at the solved frequencies, are the template
        # with S at 8 % QE on themselves; the personal set is heard with them, both on the directions they share
        frequencies = np.asarray(sofar.read_sofa(str(hrir.with_name("HRTF.sofa")), verify=False).N)
        dataset = resampled_at(read_hrtf_set(SONICOM / subject / "hrir_mesh2hrtf_48k.sofa"), frequencies)
        personal, reference = on_common_directions(read_hrtf_set(hrir), dataset)
        own = LocalisationModel(reference, reference, [-20.0, 0.0, 20.0])
        sensitivity = own.calibrate(8.0, closest=True)
        base_prediction = own.predict(sensitivity)
        prediction = LocalisationModel(personal, reference, [-20.0, 0.0, 20.0]).predict(sensitivity)
        summary.update(delta_qe_pp=round(prediction.qe - base_prediction.qe, 3),
                       delta_pe_deg=round(prediction.pe - base_prediction.pe, 3),
                       directions_compared=int(reference.irs.shape[0]))
        # ear by ear: the personal set's one ear, the other from the dataset's set
        for index, side in enumerate(("left", "right")):
            irs = reference.irs.copy()
            irs[:, index] = personal.irs[:, index]
            one = LocalisationModel(dataclasses.replace(reference, irs=irs), reference, [-20.0, 0.0, 20.0])
            alone = one.predict(sensitivity)
            summary[f"{side}_ear_only_delta_qe_pp"] = round(alone.qe - base_prediction.qe, 3)
            summary[f"{side}_ear_only_delta_pe_deg"] = round(alone.pe - base_prediction.pe, 3)
    print(f"{subject} as a new listener: frame axis {summary['frame_axis_error_deg']:.2f} deg off the dataset's y, "
          f"origin {summary['frame_origin_error_mm']:.1f} mm off its origin; fits {summary['left_fit_median_mm']:.2f} / "
          f"{summary['right_fit_median_mm']:.2f} mm (median, left / right); NumCalc {summary['cpu_hours']:.2f} CPU h "
          f"so far; ears solved {summary['ears_solved']}", flush=True)
    KEPT.mkdir(parents=True, exist_ok=True)
    (KEPT / f"{subject}.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument("--report-only", action="store_true", help="judge what has been run so far")
    args = parser.parse_args()
    if not args.report_only:
        run(args.subject, args.seed, args.cores)
    print(json.dumps(report(args.subject, args.seed)))


if __name__ == "__main__":
    main()
