"""The committed evaluation judged by the paper's own protocol: per subject, the unchanged head solved here
(``original``) is the reference and the template, S is calibrated to 8 % QE on it, and every other solved
condition is predicted with them (left ears solved, right ear from the dataset's reference HRIRs); the ``reference``
row is the dataset's own HRIRs heard with that template.

    .venv/bin/python studies/paper_protocol.py [--evaluation evaluation/sonicom] [--data-root ../shared/data/sonicom]
                                               [--update] [--also P067/ppm_hard ...]

Reads committed files only (about a minute). With ``--update`` the paper's columns of ``summary.csv``
(reporting.paper_protocol.PAPER_COLUMNS) and Figure 7 are written anew from them, as the workflow's
evaluation_report writes them. Last line (JSON): per subject S and, per condition, QE, PE and their differences from
``original`` (``delta_qe_pp``, ``delta_pe_deg``). ``--also SUBJECT/CONDITION`` judges a solve that is not in the
evaluation yet the same way (``results/<subject>/hrtf/<condition>/HRTF.sofa``, the workflow's left-ear solve);
``SUBJECT/CONDITION=FILE`` judges a left-ear HRTF kept elsewhere (e.g. ``studies/results/``).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--evaluation", type=Path, default=ROOT / "evaluation" / "sonicom")
    parser.add_argument("--data-root", type=Path, default=ROOT.parent / "shared" / "data" / "sonicom")
    parser.add_argument("--hrir", default="hrir_mesh2hrtf_48k.sofa", help="the dataset's HRIRs in each subject folder")
    parser.add_argument("--update", action="store_true", help="write the paper's columns into summary.csv and "
                                                              "redraw figure7_qe_pe.png")
    parser.add_argument("--also", nargs="+", default=[], metavar="SUBJECT/CONDITION[=FILE]",
                        help="also judge results/<subject>/hrtf/<condition>/HRTF.sofa, or FILE (a left-ear HRTF "
                             "SOFA), not with --update")
    args = parser.parse_args()
    if args.also and args.update:
        parser.error("--also judges solves outside the evaluation; it cannot be written into summary.csv")
    from reporting.evaluation_figures import figure7  # noqa: PLC0415
    from reporting.evaluation_files import left_hrtf_files, read_summary_csv, write_summary_csv  # noqa: PLC0415
    from reporting.paper_protocol import with_paper_columns  # noqa: PLC0415

    summary = args.evaluation / "summary.csv"
    rows = read_summary_csv(summary)
    subjects = list(dict.fromkeys(row["subject"] for row in rows))
    hrtfs = {(subject, condition): path for subject in subjects
             for condition, path in left_hrtf_files(args.evaluation / "sofa", subject).items()}
    for item in args.also:
        name, _, given = item.partition("=")
        subject, _, condition = name.partition("/")
        path = Path(given) if given else ROOT / "results" / subject / "hrtf" / condition / "HRTF.sofa"
        if subject not in subjects or not path.is_file():
            raise SystemExit(f"{path}: no such solve of a subject in {summary}; solve it with the workflow first")
        hrtfs[(subject, condition)] = path
        rows.append({"subject": subject, "condition": condition})
    if not any(condition == "original" for _, condition in hrtfs):
        raise SystemExit(f"{args.evaluation / 'sofa'}: no <subject>_original_left_HRTF.sofa; the paper's protocol "
                         "needs the unchanged head")
    rows = with_paper_columns(rows, hrtfs, {s: args.data_root / s / args.hrir for s in subjects})
    figures: dict[str, dict] = {}
    print(f"{'subject':8} {'condition':12} {'QE %':>7} {'PE deg':>7} {'dQE pp':>7} {'dPE deg':>7}")
    for row in rows:
        if row.get("qe_paper_percent") is None:
            continue
        print(f"{row['subject']:8} {row['condition']:12} {row['qe_paper_percent']:7.2f} {row['pe_paper_deg']:7.2f} "
              f"{row['delta_qe_paper_pp']:+7.2f} {row['delta_pe_paper_deg']:+7.2f}", flush=True)
        entry = {"qe_percent": round(row["qe_paper_percent"], 3), "pe_deg": round(row["pe_paper_deg"], 3)}
        if row["condition"] != "original":
            entry.update(delta_qe_pp=round(row["delta_qe_paper_pp"], 3), delta_pe_deg=round(row["delta_pe_paper_deg"], 3))
        figures.setdefault(row["subject"], {})[row["condition"]] = entry
    if args.update:
        write_summary_csv(summary, rows)
        figure7(read_summary_csv(summary), args.evaluation / "figure7_qe_pe.png")
        print(f"wrote the paper's columns into {summary} and redrew {args.evaluation / 'figure7_qe_pe.png'}")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
