"""Command line: ``b2014 predict`` (one target against one template) and ``b2014 compare`` (conditions
against a reference listener, with S calibrated on the reference)."""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from core.atomic import write_text_atomic

from .errors import AmtBridgeError
from .evaluation import compare_conditions, comparison_summary
from .hrtf_set import read_hrtf_set
from .model import LocalisationModel
from .plots import save_error_bars, save_prediction_matrices


def _predict(args) -> dict:
    target, template = read_hrtf_set(args.target), read_hrtf_set(args.template)
    model = LocalisationModel(target, template, args.lateral)
    sensitivity = args.sensitivity
    if args.calibrate is not None:
        sensitivity = LocalisationModel(template, template, args.lateral).calibrate(args.calibrate)
    prediction = model.predict(sensitivity)
    if args.matrix:
        save_prediction_matrices(prediction, args.matrix, title=f"{Path(args.target).name} heard with "
                                                                f"{Path(args.template).name}")
    return {"target": str(args.target), "template": str(args.template), **prediction.as_dict()}


def _compare(args) -> dict:
    conditions = {}
    for item in args.condition:
        name, _, path = item.partition("=")
        if not path:
            raise AmtBridgeError(f"condition {item!r}: write NAME=FILE.sofa")
        conditions[name] = path
    sensitivity, predictions = compare_conditions(args.reference, conditions, args.qe, args.lateral)
    if args.bars:
        save_error_bars(predictions, args.bars, title=f"template: {Path(args.reference).name}")
    if args.matrix_dir:
        for name, prediction in predictions.items():
            save_prediction_matrices(prediction, Path(args.matrix_dir) / f"{name}_matrix.png", title=name)
    return comparison_summary(args.reference, args.qe, sensitivity, predictions)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="b2014", description="baumgartner2014 sagittal-plane localisation "
                                     "model (AMT 0.9.10) on SOFA files")
    sub = parser.add_subparsers(dest="command", required=True)
    predict = sub.add_parser("predict", help="predict QE/PE of TARGET HRTFs heard by the owner of TEMPLATE")
    predict.add_argument("target", type=Path)
    predict.add_argument("template", type=Path)
    group = predict.add_mutually_exclusive_group()
    group.add_argument("--sensitivity", type=float, default=None, help="S in dB (default 0.7, AMT's)")
    group.add_argument("--calibrate", type=float, default=None, metavar="QE",
                       help="choose S so that TEMPLATE heard through itself gives QE %% quadrant errors")
    predict.add_argument("--matrix", type=Path, help="write the prediction matrices (PNG/PDF)")
    compare = sub.add_parser("compare", help="calibrate S on REFERENCE, then predict each condition with it")
    compare.add_argument("reference", type=Path)
    compare.add_argument("condition", nargs="*", help="NAME=FILE.sofa")
    compare.add_argument("--qe", type=float, default=8.0, help="reference quadrant errors after calibration (%%)")
    compare.add_argument("--bars", type=Path, help="write QE/PE bars (PNG/PDF)")
    compare.add_argument("--matrix-dir", type=Path, help="write one prediction-matrix figure per condition here")
    for sub_parser in (predict, compare):
        sub_parser.add_argument("--lateral", type=float, nargs="+", default=None,
                                help="lateral angles of the sagittal planes (deg, default -20 0 20)")
        sub_parser.add_argument("--json", type=Path, help="write the results as JSON (default: print)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        result = _predict(args) if args.command == "predict" else _compare(args)
    except AmtBridgeError as exc:
        print(f"b2014: error: {exc}", file=sys.stderr)
        return 2
    text = json.dumps(result, indent=2) + "\n"
    if args.json:
        write_text_atomic(args.json, text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
