"""Where the reciprocal ear source sits, and how far that moves the solved DTFs from the dataset's reference.

    .venv/bin/python studies/ear_source.py [--subject P143] [--frequencies 9000 14400] [--speed-of-sound 346.18]
        [--rules ray_exit canal_floor assign_materials given_point] [--source-at X Y Z] [--canal-area MM2] [--work DIR]

The subject's unchanged SONICOM head (``head_graded_left.ply``, the ground truth) is exported once per source rule
on the reference SOFA's 793 directions, left ear only, at frequencies of the reference's own 150 Hz grid (so the
reference HRTF is exact there): ``ray_exit``, the source faces at the exit of the ray from the interaural centre
along +y (the former rule); ``canal_floor``, the middle of the canal floor the surface leads down into from there
(``mesh2hrtf_io.ear_canal``, the rule now; ``--canal-area`` sets its area); ``assign_materials``, the face Mesh2HRTF's
AssignMaterials operator picks (the one nearest the +y axis among the innermost faces within 2 mm of it; not the
face the dataset's Blender project marks); ``given_point``, the face nearest ``--source-at`` (e.g. that marked
face). NumCalc solves each, one step at a time; each solved DTF
(dB, the mean over directions removed) is compared with the reference's (the HRIRs' exact DFT). Finished steps
stay in ``--work``, so an interrupted run continues.
``--speed-of-sound`` solves with another c than Mesh2HRTF's exporter default (the reference may have used another).
Last line (JSON): per rule and frequency the median and 95th percentile of |ΔDTF| (dB) over the directions,
the distance between the first two sources (mm) and the seconds per step.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SONICOM = ROOT.parent / "shared" / "data" / "sonicom"


def exit_faces(mesh, min_area_mm2: float = 4.0) -> np.ndarray:
    """The former rule: the faces nearest the ray's exit point (outward along +y) up to ``min_area_mm2``."""
    from mesh2hrtf_io.ear_canal import _ray_exit, faces_around

    left = np.array([0.0, 1.0, 0.0])
    hit, _ = _ray_exit(mesh, left, "left", "head")
    return faces_around(mesh, hit, left, min_area_mm2)


def assign_materials_face(mesh, tolerance_mm: float = 2.0) -> np.ndarray:
    """Mesh2HRTF's AssignMaterials rule for the left ear: among the faces whose centre lies within ``tolerance_mm``
    of the y axis in x and in z at y > 0, those at most ``tolerance_mm`` beyond the smallest y; of these, the one
    with the smallest |x| + |z|."""
    centre = mesh.triangles_center
    near = np.flatnonzero((centre[:, 1] > 0) & (np.abs(centre[:, 0]) < tolerance_mm)
                          & (np.abs(centre[:, 2]) < tolerance_mm))
    if near.size == 0:
        raise SystemExit(f"no face within {tolerance_mm} mm of the +y axis")
    inner = near[centre[near, 1] < centre[near, 1].min() + tolerance_mm]
    return inner[[np.argmin(np.abs(centre[inner, 0]) + np.abs(centre[inner, 2]))]]


def nearest_face(mesh, point_mm) -> np.ndarray:
    """The face whose centre lies nearest ``point_mm`` (e.g. a source face read from another project)."""
    if point_mm is None:
        raise SystemExit("rule given_point needs --source-at X Y Z (mm)")
    return np.array([np.argmin(np.linalg.norm(mesh.triangles_center - np.asarray(point_mm), axis=1))])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--frequencies", type=float, nargs="+", default=[9000.0, 14400.0])
    parser.add_argument("--speed-of-sound", type=float, default=None, help="m/s (default: Mesh2HRTF's 346.18)")
    parser.add_argument("--rules", nargs="+", default=["ray_exit", "canal_floor", "assign_materials"],
                        help="ray_exit, canal_floor, assign_materials, given_point (needs --source-at)")
    parser.add_argument("--canal-area", type=float, default=None,
                        help="rule canal_floor: the source's area (mm^2; default: the pipeline's rule's)")
    parser.add_argument("--source-at", type=float, nargs=3, metavar=("X", "Y", "Z"),
                        help="rule given_point: the face whose centre is nearest this point (mm, head frame)")
    parser.add_argument("--numcalc", default="")
    parser.add_argument("--work", type=Path, default=ROOT / "results" / "benchmarks" / "ear_source")
    args = parser.parse_args()

    import sofar
    import trimesh

    from amt_bridge.dtf import directional_levels_db
    from mesh2hrtf_io.constants import SPEED_OF_SOUND_M_S
    from mesh2hrtf_io.grids import grid_from_sofa
    from mesh2hrtf_io.numcalc import find_numcalc, run_step
    from mesh2hrtf_io.project import write_project
    from mesh2hrtf_io.results import read_eval_grid_pressure
    from mesh2hrtf_io.ear_canal import ear_canal_elements

    folder = SONICOM / args.subject
    head = trimesh.load(folder / "head_graded_left.ply", process=False, force="mesh")
    reference = sofar.read_sofa(str(folder / "hrir_mesh2hrtf_48k.sofa"), verbose=False)
    rate = float(np.atleast_1d(reference.Data_SamplingRate)[0])
    impulse = reference.Data_IR[:, 0, :]
    times = np.arange(impulse.shape[1]) / rate
    numcalc = find_numcalc(args.numcalc or None)
    grid = grid_from_sofa(folder / "hrir_mesh2hrtf_48k.sofa", name="Directions")
    speed = args.speed_of_sound or SPEED_OF_SOUND_M_S
    canal_area = {} if args.canal_area is None else {"min_area_mm2": args.canal_area}
    rule_of = {"ray_exit": exit_faces, "canal_floor": lambda mesh: ear_canal_elements(mesh, "left", **canal_area),
               "assign_materials": assign_materials_face,
               "given_point": lambda mesh: nearest_face(mesh, args.source_at)}
    rules = {name: rule_of[name](head) for name in args.rules}
    centres = {name: head.triangles_center[faces].mean(axis=0) for name, faces in rules.items()}
    for name, centre in centres.items():
        print(f"{args.subject}: {name} source ({len(rules[name])} faces, "
              f"{head.area_faces[rules[name]].sum():.2f} mm^2) at {np.round(centre, 1)} mm")
    figures: dict = {"subject": args.subject, "speed_of_sound_m_s": speed}
    if len(centres) > 1:
        first, second = list(centres.values())[:2]
        figures["source_gap_mm"] = round(float(np.linalg.norm(first - second)), 2)
    folder_name = ("_".join(f"{f:.0f}" for f in args.frequencies)
                   + ("" if speed == SPEED_OF_SOUND_M_S else f"_c{speed:g}")
                   + ("" if args.canal_area is None else f"_area{args.canal_area:g}"))
    for name, faces in rules.items():
        project = args.work / args.subject / folder_name / name
        if not (project / "parameters.json").is_file():
            write_project(project, head.vertices, head.faces, {"left": faces}, [grid], args.frequencies,
                          source_type="Left ear", title=f"{args.subject}_{name}", speed_of_sound_m_s=speed)
        source = project / "NumCalc" / "source_1"
        for step, frequency in enumerate(args.frequencies, start=1):
            start = time.perf_counter()
            status = run_step(numcalc, source, step, len(grid.points_m))
            # a resumed step reports the seconds NumCalc took when it was solved
            seconds = sum(a.get("seconds", 0.0) for a in status.get("attempts", [])) or time.perf_counter() - start
            solved = directional_levels_db(read_eval_grid_pressure(source, step))
            truth = directional_levels_db(impulse @ np.exp(-2j * np.pi * frequency * times))
            error = np.abs(solved - truth)
            key = f"{name}_{frequency:.0f}hz"
            figures[f"{key}_median_db"] = round(float(np.median(error)), 3)
            figures[f"{key}_p95_db"] = round(float(np.percentile(error, 95)), 3)
            figures[f"{key}_seconds"] = round(seconds, 1)
            print(f"  {name:12s} {frequency:8.0f} Hz: |ΔDTF| to the reference median {np.median(error):.2f} dB, "
                  f"p95 {np.percentile(error, 95):.2f} dB ({seconds:.0f} s)")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
