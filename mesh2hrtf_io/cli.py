"""Command line: ``m2h export | solve | collect | cost | spikes | doctor`` for Mesh2HRTF projects."""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

import numpy as np

from core.errors import PipelineError

from .errors import Mesh2HrtfIoError
from .frequency_sets import check_frequency_set, frequencies_from_spec, frequency_list, presets


def _steps(text: str) -> list[int]:
    """``--steps`` value: 1-based step numbers separated by commas ("30", "1,2,30")."""
    try:
        steps = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give 1-based step numbers separated by commas, e.g. 1,2,30") from None
    if not steps or min(steps) < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: steps are numbered from 1")
    return steps


def _export_frequencies(args) -> np.ndarray:
    """The export's set: an explicit list, a preset, or the linear grid of --fmin/--fmax/--fstep."""
    if args.frequencies:
        return check_frequency_set(args.frequencies, "--frequencies")
    if args.preset:
        return frequencies_from_spec({"preset": args.preset}, "--preset")
    return frequency_list(args.fmin or args.fstep, args.fmax, args.fstep)


def _export(args) -> dict:
    import trimesh  # noqa: PLC0415

    from .ear_canal import ear_canal_elements  # noqa: PLC0415

    from .grids import grid_from_sofa, sagittal_grid  # noqa: PLC0415
    from .project import write_project  # noqa: PLC0415

    if not args.head.is_file():
        raise Mesh2HrtfIoError(f"{args.head}: no such mesh file")
    head = trimesh.load(args.head, process=False, force="mesh")
    sides = {"both": ("left", "right"), "left": ("left",), "right": ("right",)}[args.ears]
    ears = {side: ear_canal_elements(head, side, source=str(args.head)) for side in sides}
    grids = [sagittal_grid(polar_step_deg=args.polar_step)] + [grid_from_sofa(path) for path in args.grid_sofa]
    frequencies = _export_frequencies(args)
    layout = write_project(args.project, head.vertices, head.faces, ears, grids, frequencies,
                           source_type={"both": "Both ears", "left": "Left ear", "right": "Right ear"}[args.ears],
                           title=args.head.stem, compute_hrirs=args.hrirs,
                           numcalc_cluster_size=args.cluster_size)
    return {"project": str(args.project), "elements": layout.n_object_elements, "ear_ranges": layout.ear_ranges,
            "frequencies": len(frequencies), "grids": [g.name for g in grids],
            "numcalc_clusters": json.loads((args.project / "numcalc_clusters.json").read_text())}


def _solve(args) -> dict:
    if args.solver == "embedded":
        from .bem import use_device  # noqa: PLC0415
        from .embedded import solve_project_embedded  # noqa: PLC0415

        use_device(args.device)
        return solve_project_embedded(args.project, args.steps)
    from .numcalc import solve_project_numcalc  # noqa: PLC0415

    return solve_project_numcalc(args.project, args.numcalc, args.steps)


def _collect(args) -> dict:
    from .sofa_out import collect_sofa  # noqa: PLC0415

    return {"files": [str(p) for p in collect_sofa(args.project, args.output, hrir_sampling_rate_hz=args.hrir_rate,
                                                   hrir_samples=args.hrir_samples)]}


def _cost(args) -> dict:
    from .cost import project_cost  # noqa: PLC0415

    return project_cost(args.project, args.solver, args.numcalc, device=args.device).as_dict()


def _spikes(args) -> dict:
    from .surface_spikes import SPIKE_MARGIN_DB, project_spikes  # noqa: PLC0415

    if not (args.project / "NumCalc").is_dir():
        raise Mesh2HrtfIoError(f"{args.project}: no NumCalc folder (not a Mesh2HRTF project)")
    return project_spikes(args.project, SPIKE_MARGIN_DB if args.margin_db is None else args.margin_db)


def _doctor(args) -> dict:
    from .doctor import doctor  # noqa: PLC0415

    return doctor(args.numcalc, probe=args.probe)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="m2h", description="Mesh2HRTF projects: export, solve, collect SOFA, cost")
    sub = parser.add_subparsers(dest="command", required=True)
    export = sub.add_parser("export", help="write a project from a closed head mesh in millimetres")
    export.add_argument("head", type=Path)
    export.add_argument("project", type=Path)
    export.add_argument("--ears", choices=["both", "left", "right"], default="both")
    export.add_argument("--fmin", type=float, default=None, help="lowest frequency (Hz; default = step)")
    export.add_argument("--fmax", type=float, default=18000.0)
    export.add_argument("--fstep", type=float, default=100.0)
    export.add_argument("--preset", choices=sorted(presets()), default=None,
                        help="a named frequency set (mesh2hrtf_io/data/frequency_sets.yaml), e.g. evaluation")
    export.add_argument("--frequencies", type=float, nargs="*", default=None, help="an explicit list (Hz)")
    export.add_argument("--cluster-size", type=lambda v: v if v == "auto" else float(v), default="auto",
                        help="NumCalc level-0 cluster size in m (0: NumCalc's default; auto: from the mesh)")
    export.add_argument("--polar-step", type=float, default=2.5, help="sagittal-plane grid step (deg)")
    export.add_argument("--grid-sofa", type=Path, nargs="*", default=[], help="extra grids from SOFA source positions")
    export.add_argument("--hrirs", action="store_true", help="ask for HRIR SOFA files too")
    for name, helptext in (("solve", "solve the missing frequency steps"), ("cost", "predict CPU-hours and RAM")):
        command = sub.add_parser(name, help=helptext)
        command.add_argument("project", type=Path)
        command.add_argument("--solver", choices=["embedded", "numcalc"], default="embedded")
        command.add_argument("--device", choices=["auto", "numba", "opencl", "cuda"], default="auto",
                             help="embedded solver's backend (mesh2hrtf_io/backends.py)")
        command.add_argument("--numcalc", default=None, help="NumCalc binary (default: PATH)")
        if name == "solve":
            # one value per --steps (a comma list, or the option repeated): with nargs="*", "--steps 30 PROJECT"
            # took the project for a step ("invalid int value"); now the project stays positional wherever it stands
            command.add_argument("--steps", type=_steps, action="extend", default=None, metavar="STEP[,STEP...]",
                                 help="1-based steps, e.g. --steps 30 or --steps 1,2,30 (default: all)")
    from .sofa_out import HRIR_RATE_HZ, HRIR_SAMPLES  # noqa: PLC0415

    collect = sub.add_parser("collect", help="write HRTF/HRIR SOFA files of a solved project")
    collect.add_argument("project", type=Path)
    collect.add_argument("--output", type=Path, default=None)
    collect.add_argument("--hrir-rate", type=float, default=HRIR_RATE_HZ, help="rate of HRIRs rebuilt from a sparse set (Hz)")
    collect.add_argument("--hrir-samples", type=int, default=HRIR_SAMPLES, help="taps of HRIRs rebuilt from a sparse set")
    spikes = sub.add_parser("spikes", help="boundary elements of solved steps far louder than the ear's source")
    spikes.add_argument("project", type=Path)
    spikes.add_argument("--margin-db", type=float, default=None, help="dB above the source's loudest element "
                        "that make a spike (default 6)")
    check = sub.add_parser("doctor", help="say which solver is usable here, and why not")
    check.add_argument("--numcalc", default=None, help="NumCalc binary to check (default: PATH, then .venv/bin)")
    check.add_argument("--probe", action="store_true", help="probe the embedded solver's opencl and cuda backends "
                       "now (child processes; verdicts cached per machine)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    handlers = {"export": _export, "solve": _solve, "collect": _collect, "cost": _cost, "doctor": _doctor,
                "spikes": _spikes}
    try:
        result = handlers[args.command](args)
    except PipelineError as exc:
        print(f"m2h: error: {exc}", file=sys.stderr)
        return 2
    sys.stdout.write(json.dumps(result, indent=2, default=str) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
