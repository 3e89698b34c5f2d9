"""Command line of the parametric pinna model: `ppm build-template`, `ppm render`, `ppm sheet`, `ppm pose`."""
from __future__ import annotations

import argparse
import logging
import sys

from .errors import PpmError


def _build_template(args: argparse.Namespace) -> None:
    from .template.build import build_template_folder

    build_template_folder(args.data_root, args.out, exclude=args.exclude, topology_dir=args.topology,
                          edge_mm=args.edge_mm, margin_mm=args.margin_mm, rounds=args.rounds)


def _model(args: argparse.Namespace):
    from .model import PinnaModel

    return PinnaModel.from_template(args.template)


def _params(args: argparse.Namespace):
    from .parameters import PinnaParameters

    if args.parameters is None:
        return PinnaParameters.default()
    return PinnaParameters.read(args.parameters, out_of_range="clip" if args.clip else "raise")


def _render(args: argparse.Namespace) -> None:
    from .render import render_model

    render_model(_model(args), args.out, _params(args))


def _sheet(args: argparse.Namespace) -> None:
    from .render import render_range_sheet

    render_range_sheet(_model(args), args.out)


def _pose(args: argparse.Namespace) -> None:
    model = _model(args)
    params = _params(args)
    model.set_parameters(params)
    for out in args.out:
        if out.endswith(".blend"):
            model.save_blend(out)
        elif out.endswith((".csv", ".json")):
            params.write(out)
        else:
            model.export(out)


def _align(args: argparse.Namespace) -> None:
    import json

    from .align import AlignSettings, align, prepare_target
    from .align.pose_by_fit import align_any_pose, pose_summary
    from .align.report import write_alignment
    from .align.widen import refit_widened

    model = _model(args)
    target = prepare_target(args.target, side=args.side, margin_mm=args.margin_mm, segment=not args.no_segment,
                            scan_pose=args.scan_pose)
    if target.pose is not None:  # the PPM decides between rigid poses that fit about equally
        result, target = align_any_pose(model, target, AlignSettings())
    else:
        result = align(model, target, AlignSettings())
    result, target, widening = refit_widened(model, target, result, AlignSettings())
    summary = write_alignment(args.out, model, target, result,
                              extra={"target_widening": widening, **pose_summary(target)})
    print(json.dumps(summary["distance_target_to_ppm"]))
    for warning in summary["warnings"]:
        print(f"ppm: warning: {warning}", file=sys.stderr)


def _snap(args: argparse.Namespace) -> None:
    from .landmarks import LANDMARKS_NAME, snap_landmarks
    from .template.store import load_template

    template = load_template(args.template)
    snap_landmarks(template.folder / LANDMARKS_NAME, template.vertices_mm)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `ppm` command; returns the exit status."""
    parser = argparse.ArgumentParser(prog="ppm", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress")
    sub = parser.add_subparsers(dest="command", required=True)

    build = sub.add_parser("build-template", help="build an average left pinna template from scans")
    build.add_argument("--data-root", required=True, help="folder of <subject>/pinna_{left,right}_crop.ply (mm)")
    build.add_argument("--out", required=True, help="output template folder")
    build.add_argument("--exclude", nargs="*", default=[], help="subjects to leave out")
    build.add_argument("--topology", default=None, help="template folder whose vertex order to reuse")
    build.add_argument("--edge-mm", type=float, default=1.0, help="target edge length in mm")
    build.add_argument("--margin-mm", type=float, default=6.0, help="width of the skin ring around the pinna, mm")
    build.add_argument("--rounds", type=int, default=2, help="registration rounds")
    build.set_defaults(func=_build_template)

    def model_options(command: argparse.ArgumentParser) -> None:
        command.add_argument("--template", default=None, help="template folder (default: the packaged one)")
        command.add_argument("--parameters", default=None, help="parameter file (.csv or .json); default: rest pose")
        command.add_argument("--clip", action="store_true", help="clamp out-of-range parameters instead of failing")

    render = sub.add_parser("render", help="PNG of the posed PPM with its armature (off-screen)")
    render.add_argument("out", help="output PNG")
    model_options(render)
    render.set_defaults(func=_render)

    sheet = sub.add_parser("sheet", help="PNG of every curve and shape key at its range limits")
    sheet.add_argument("out", help="output PNG")
    model_options(sheet)
    sheet.set_defaults(func=_sheet)

    pose = sub.add_parser("pose", help="pose the PPM and write .blend / .ply / .stl / .obj / .csv / .json")
    pose.add_argument("out", nargs="+", help="output files; the format follows the suffix")
    model_options(pose)
    pose.set_defaults(func=_pose)

    fit = sub.add_parser("align", help="fit the PPM to a pinna scan and write parameters, meshes and distances")
    fit.add_argument("target", help="pinna scan (PLY/STL/OBJ, mm, +x front, +y left, +z up)")
    fit.add_argument("--out", required=True, help="output folder")
    fit.add_argument("--side", choices=("left", "right"), default="left", help="which ear the scan holds")
    fit.add_argument("--scan-pose", choices=("project_frame", "any"), default="project_frame",
                     help="any: the scan may have any orientation, offset, unit (mm/cm/m) and side; its pose is "
                          "found, or the scan is refused with the reason (--side is then ignored)")
    fit.add_argument("--margin-mm", type=float, default=3.0, help="skin ring kept around the detected pinna, mm")
    fit.add_argument("--no-segment", action="store_true", help="the scan is the pinna alone: do not cut it out")
    fit.add_argument("--template", default=None, help="template folder (default: the packaged one)")
    fit.set_defaults(func=_align)

    snap = sub.add_parser("snap-landmarks", help="snap a template's picked landmark positions to vertex ids")
    snap.add_argument("template", help="template folder holding landmarks.yaml")
    snap.set_defaults(func=_snap)

    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s")
    try:
        args.func(args)
    except PpmError as exc:
        hint = " (on the command line: --clip)" if "out_of_range='clip'" in str(exc) else ""
        print(f"ppm: error: {exc}{hint}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
