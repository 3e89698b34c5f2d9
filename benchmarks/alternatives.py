"""What a personal HRTF buys (issue 53): every condition of the committed evaluation beside what a listener would use
otherwise (another subject's HRTFs, measured dummy heads and listeners, the posed template, the defective scan made
watertight), ranked by the paper's protocol. Reads committed files only, no solve (about a minute):

    .venv/bin/python benchmarks/alternatives.py [--evaluation evaluation/sonicom] [--config config/paper_sonicom.yaml]

The summary's paper columns (``summary.csv``), the committed left-ear HRTFs (``sofa/``) and the dataset's HRIRs give
the conditions; ``reporting.nonindividual`` judges the non-individual sets from the committed SOFA files afresh, and
``reporting.ranking`` ranks them. Last line (JSON): subjects, nonindividual_sets, nonindividual_median_dqe_pp and
nonindividual_min_dqe_pp (per subject), default_ppm_dqe_pp (worst subject), scan_hard_dqe_pp (per subject; null
where not solved, with the reason in scan_hard_not_solved), ppm_detail_beats_all and detail_hard_beats_all (1 or 0),
ppm_detail_share_min and detail_hard_share_min (the share of the median non-individual penalty removed, worst
subject), and the same shares over the other subjects' sets alone (``*_same_solver_share_min``).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SONICOM = ROOT.parent / "shared" / "data" / "sonicom"


def _worst(values: list[float | None], low: bool = True) -> float | None:
    known = [v for v in values if v is not None]
    return (min(known) if low else max(known)) if known else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--evaluation", type=Path, default=ROOT / "evaluation" / "sonicom")
    parser.add_argument("--config", type=Path, default=ROOT / "config" / "paper_sonicom.yaml")
    parser.add_argument("--data-root", type=Path, default=SONICOM)
    args = parser.parse_args()
    import os

    import yaml

    from reporting.evaluation_files import left_hrtf_files, read_summary_csv
    from reporting.nonindividual import MeasuredSet, nonindividual_rows
    from reporting.ranking import beats_every_alternative, median_penalties, ranking_markdown, ranking_rows

    os.chdir(ROOT)  # the config's measured sets are relative to the project root
    config = yaml.safe_load(args.config.read_text())["evaluation"]
    summary = read_summary_csv(args.evaluation / "summary.csv")
    subjects = list(dict.fromkeys(row["subject"] for row in summary))
    originals = {s: left_hrtf_files(args.evaluation / "sofa", s).get("original") for s in subjects}
    originals = {s: path for s, path in originals.items() if path is not None}
    measured = [MeasuredSet.from_config(entry) for entry in config.get("nonindividual") or []]
    nonindividual = nonindividual_rows(subjects, originals,
                                       {s: args.data_root / s / "hrir_mesh2hrtf_48k.sofa" for s in subjects}, measured)
    ranking = ranking_rows(summary, nonindividual)
    print(ranking_markdown(ranking))

    def delta(subject: str, condition: str) -> float | None:
        row = next((r for r in ranking if r["subject"] == subject and r["condition"] == condition), None)
        return None if row is None else round(row["delta_qe_pp"], 3)

    def share(subject: str, condition: str, key: str = "share_removed") -> float | None:
        row = next((r for r in ranking if r["subject"] == subject and r["condition"] == condition), None)
        return None if row is None or row[key] is None else round(row[key], 4)

    hard = [s for s in subjects if any(r["subject"] == s and r["condition"].endswith("_hard") for r in ranking)]
    not_solved = {s: reason for s in subjects
                  for condition, reason in ((config.get("not_solved") or {}).get(s) or {}).items()
                  if condition == "scan_hard"}
    detail_beats = [beats_every_alternative(ranking, s, "ppm_detail") for s in subjects]
    hard_beats = [beats_every_alternative(ranking, s, "ppm_detail_hard") for s in hard]
    for s in subjects:
        every, same = median_penalties(nonindividual, s)
        print(f"{s}: median non-individual ΔQE {every:+.2f} pp (every set), {same:+.2f} pp (other subjects); "
              f"ppm_detail {delta(s, 'ppm_detail')} pp removes {share(s, 'ppm_detail')} of it; beats every "
              f"alternative: {beats_every_alternative(ranking, s, 'ppm_detail')}")
    for s in hard:
        print(f"{s}: ppm_detail_hard {delta(s, 'ppm_detail_hard')} pp, scan_hard {delta(s, 'scan_hard')} pp, "
              f"default_ppm {delta(s, 'default_ppm')} pp; ppm_detail_hard beats every alternative: "
              f"{beats_every_alternative(ranking, s, 'ppm_detail_hard')}, removes {share(s, 'ppm_detail_hard')}")
    print(json.dumps({
        "subjects": subjects,
        "nonindividual_sets": sorted({r["condition"] if not r["condition"].startswith("other_") else "other subjects"
                                      for r in nonindividual}),
        "nonindividual_median_dqe_pp": {s: round(median_penalties(nonindividual, s)[0], 3) for s in subjects},
        "nonindividual_same_solver_median_dqe_pp": {s: round(median_penalties(nonindividual, s)[1], 3)
                                                    for s in subjects},
        "nonindividual_min_dqe_pp": {s: round(min(r["delta_qe_pp"] for r in nonindividual if r["subject"] == s), 3)
                                     for s in subjects},
        "default_ppm_dqe_pp": _worst([delta(s, "default_ppm") for s in subjects], low=False),
        "scan_hard_dqe_pp": {s: delta(s, "scan_hard") for s in hard},
        "scan_hard_not_solved": not_solved,
        "ppm_detail_beats_all": int(all(b is True for b in detail_beats)),
        "detail_hard_beats_all": int(bool(hard_beats) and all(b is True for b in hard_beats)),
        "ppm_detail_share_min": _worst([share(s, "ppm_detail") for s in subjects]),
        "detail_hard_share_min": _worst([share(s, "ppm_detail_hard") for s in hard]),
        "ppm_detail_same_solver_share_min": _worst([share(s, "ppm_detail", "share_removed_same_solver")
                                                    for s in subjects]),
        "detail_hard_same_solver_share_min": _worst([share(s, "ppm_detail_hard", "share_removed_same_solver")
                                                     for s in hard]),
    }))


if __name__ == "__main__":
    main()
