"""The committed evaluation judged by the paper's own protocol: per subject, the unchanged head solved here
(``original``) is the reference and the template, S is calibrated to 8 % QE on it, and every other solved
condition is predicted with them (left ears solved, right ear from the dataset's reference HRIRs).

    .venv/bin/python studies/paper_protocol.py [--evaluation evaluation/sonicom] [--data-root ../shared/data/sonicom]

Reads committed files only (about a minute). Last line (JSON): per subject S and, per condition, QE, PE and their
differences from ``original`` (``delta_qe_pp``, ``delta_pe_deg``).
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
    args = parser.parse_args()
    from reporting.paper_protocol import paper_protocol  # noqa: PLC0415

    sofa = args.evaluation / "sofa"
    subjects = sorted({path.name.split("_")[0] for path in sofa.glob("*_original_left_HRTF.sofa")})
    if not subjects:
        raise SystemExit(f"{sofa}: no <subject>_original_left_HRTF.sofa; the paper's protocol needs the unchanged head")
    figures = {}
    print(f"{'subject':8} {'condition':12} {'QE %':>7} {'PE deg':>7} {'dQE pp':>7} {'dPE deg':>7}")
    for subject in subjects:
        conditions = {path.name[len(subject) + 1:-len("_left_HRTF.sofa")]: path
                      for path in sorted(sofa.glob(f"{subject}_*_left_HRTF.sofa"))}
        reference = conditions.pop("original")
        result = paper_protocol(reference, conditions, args.data_root / subject / args.hrir)
        base = result["reference"]
        rows = {"original": {"qe_percent": round(base["qe_percent"], 3), "pe_deg": round(base["pe_deg"], 3)}}
        for name in conditions:
            qe, pe = result[name]["qe_percent"], result[name]["pe_deg"]
            rows[name] = {"qe_percent": round(qe, 3), "pe_deg": round(pe, 3),
                          "delta_qe_pp": round(qe - base["qe_percent"], 3), "delta_pe_deg": round(pe - base["pe_deg"], 3)}
        for name, row in rows.items():
            print(f"{subject:8} {name:12} {row['qe_percent']:7.2f} {row['pe_deg']:7.2f} "
                  f"{row.get('delta_qe_pp', 0.0):+7.2f} {row.get('delta_pe_deg', 0.0):+7.2f}", flush=True)
        figures[subject] = {"sensitivity_db": round(result["sensitivity_db"], 4), "conditions": rows}
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
