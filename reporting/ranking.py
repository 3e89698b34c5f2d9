"""What a personal HRTF buys: per subject, every condition of the evaluation and every alternative a listener has
(a dummy head, someone else's HRTFs, the template ear, their own defective scan made watertight), ranked by the
paper's protocol (``original`` as reference and template, S at 8 % QE on it; ΔQE in pp, ΔPE in deg).

The share of the non-individual penalty a condition removes is ``(median non-individual ΔQE - ΔQE) / median
non-individual ΔQE``: 100 % is the listener's own ear, 0 % no better than the typical non-individual set. The median
is taken over every non-individual set of the subject (``share_removed``) and, more strictly, over the other
subjects' sets alone (``share_removed_same_solver``: solved like the subject's own, on the same grid, so that they
differ from the template only by whose head they are, not also by measurement against simulation).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

#: Columns of ranking.csv, in order.
RANKING_COLUMNS = ("subject", "rank", "condition", "kind", "directions", "qe_percent", "pe_deg", "delta_qe_pp",
                   "delta_pe_deg", "share_removed", "share_removed_same_solver")

#: What each evaluation condition is, for the ranking's ``kind`` column (non-individual rows bring their own).
CONDITION_KINDS = {"reference": "own head, the dataset's solve", "own_pinna": "own ear, stitched back (control)",
                   "ppm": "personal: PPM fit", "ppm_detail": "personal: PPM fit + detail layer",
                   "default_ppm": "template ear, posed only", "ppm_hard": "defective scan: PPM fit",
                   "ppm_detail_hard": "defective scan: PPM fit + detail layer",
                   "nricp_hard": "defective scan: free-form NRICP", "scan_hard": "defective scan made watertight"}
#: The kinds of the non-individual sets; "dataset subject" is the same-solver one.
NONINDIVIDUAL_KINDS = ("dataset subject", "dummy head", "listener")
SAME_SOLVER_KIND = "dataset subject"


def _share(penalty_pp: float | None, delta_qe_pp: float) -> float | None:
    if penalty_pp is None or penalty_pp <= 0:
        return None
    return (penalty_pp - delta_qe_pp) / penalty_pp


def median_penalties(nonindividual: list[dict], subject: str) -> tuple[float | None, float | None]:
    """The subject's median non-individual ΔQE (pp): over every set, and over the other dataset subjects' alone."""
    every = [r["delta_qe_pp"] for r in nonindividual if r["subject"] == subject]
    same = [r["delta_qe_pp"] for r in nonindividual if r["subject"] == subject and r["kind"] == SAME_SOLVER_KIND]
    return (float(np.median(every)) if every else None, float(np.median(same)) if same else None)


def ranking_rows(summary: list[dict], nonindividual: list[dict]) -> list[dict]:
    """One row per subject and condition or alternative (:data:`RANKING_COLUMNS`), ranked by ΔQE by the paper's
    protocol (ties by ΔPE). ``summary``: the evaluation's rows with the paper's columns; ``original`` is the
    reference of the ranking and left out; ``nonindividual``: :func:`reporting.nonindividual.nonindividual_rows`."""
    out = []
    subjects = list(dict.fromkeys([r["subject"] for r in summary] + [r["subject"] for r in nonindividual]))
    for subject in subjects:
        every, same = median_penalties(nonindividual, subject)
        rows = []
        for row in summary:
            if row["subject"] != subject or row["condition"] == "original" or row.get("delta_qe_paper_pp") is None:
                continue
            rows.append({"subject": subject, "condition": row["condition"],
                         "kind": CONDITION_KINDS.get(row["condition"], row["condition"]), "directions": None,
                         "qe_percent": row["qe_paper_percent"], "pe_deg": row["pe_paper_deg"],
                         "delta_qe_pp": row["delta_qe_paper_pp"], "delta_pe_deg": row["delta_pe_paper_deg"]})
        rows += [{key: r[key] for key in ("subject", "condition", "kind", "directions", "qe_percent", "pe_deg",
                                          "delta_qe_pp", "delta_pe_deg")}
                 for r in nonindividual if r["subject"] == subject]
        rows.sort(key=lambda r: (r["delta_qe_pp"], r["delta_pe_deg"]))
        for rank, row in enumerate(rows, start=1):
            row.update(rank=rank, share_removed=_share(every, row["delta_qe_pp"]),
                       share_removed_same_solver=_share(same, row["delta_qe_pp"]))
        out += rows
    return out


def beats_every_alternative(ranking: list[dict], subject: str, condition: str,
                            alternatives: tuple[str, ...] = ("default_ppm", "scan_hard")) -> bool | None:
    """Whether ``condition`` comes nearer the own ear than every non-individual set and each of ``alternatives``
    the subject has, in |ΔQE| and |ΔPE| both; None where the subject has no such condition."""
    mine = next((r for r in ranking if r["subject"] == subject and r["condition"] == condition), None)
    if mine is None:
        return None
    others = [r for r in ranking if r["subject"] == subject
              and (r["kind"] in NONINDIVIDUAL_KINDS or r["condition"] in alternatives)]
    return all(abs(mine["delta_qe_pp"]) < abs(r["delta_qe_pp"]) and abs(mine["delta_pe_deg"]) < abs(r["delta_pe_deg"])
               for r in others)


def write_ranking_csv(path: str | os.PathLike, rows: list[dict]) -> Path:
    """ranking.csv (:data:`RANKING_COLUMNS`; shares as fractions, 3 decimals), written atomically."""
    from .evaluation_files import write_csv  # noqa: PLC0415

    return write_csv(path, rows, RANKING_COLUMNS)


def read_ranking_csv(path: str | os.PathLike) -> list[dict]:
    """ranking.csv back as rows (numbers as floats, empty cells as None)."""
    import csv  # noqa: PLC0415

    text_columns = ("subject", "condition", "kind")
    with open(path, newline="") as handle:
        return [{key: (value if key in text_columns else (float(value) if value != "" else None))
                 for key, value in raw.items()} for raw in csv.DictReader(handle)]


#: How the ranking is made, for the pages that show it.
RANKING_TEXT = ("Every condition beside what a listener would use otherwise, by the paper's protocol (the subject's "
                "own head solved here as reference and template, S at 8 % QE on it): the other subjects' heads "
                "solved the same way (both ears theirs), measured dummy heads and listeners (sampled at the "
                "evaluation's frequencies and rebuilt at 48 kHz like the solved heads; compared on the template "
                "directions they have within 2 deg, against the template's own QE and PE there). 'penalty removed' "
                "is (median non-individual ΔQE - ΔQE) / median non-individual ΔQE, over every set, and over the "
                "other subjects' sets alone (same solver and grid: the stricter figure, since a measured set also "
                "differs from a simulated template by being measured).")


def _percent(value: float | None) -> str:
    return "–" if value is None else f"{100.0 * value:.0f} %"


def ranking_markdown(rows: list[dict]) -> str:
    """One Markdown table per subject: rank, condition, what it is, directions compared, ΔQE, ΔPE and both shares."""
    parts = []
    for subject in dict.fromkeys(r["subject"] for r in rows):
        mine = [r for r in rows if r["subject"] == subject]
        every, same = median_penalties([r for r in mine if r["kind"] in NONINDIVIDUAL_KINDS], subject)
        lines = [f"**{subject}** (median non-individual ΔQE {every:+.2f} pp over every set, {same:+.2f} pp over the "
                 "other subjects' sets)" if every is not None and same is not None else f"**{subject}**", "",
                 "| rank | condition | what it is | directions | ΔQE (pp) | ΔPE (deg) | penalty removed | "
                 "same-solver penalty removed |", "|---|---|---|---|---|---|---|---|"]
        for r in mine:
            directions = "all" if r.get("directions") in (None, "") else f"{int(r['directions'])}"
            lines.append(f"| {int(r['rank'])} | `{r['condition']}` | {r['kind']} | {directions} | "
                         f"{r['delta_qe_pp']:+.2f} | {r['delta_pe_deg']:+.2f} | {_percent(r['share_removed'])} | "
                         f"{_percent(r['share_removed_same_solver'])} |")
        parts.append("\n".join(lines))
    return "\n\n".join(parts) + "\n"


#: The README's headline table, between these markers: every condition and alternative per subject.
HEADLINE_BEGIN = "<!-- headline: python -m reporting.ranking --update README.md -->"
HEADLINE_END = "<!-- end of headline -->"
#: The headline's rows: (label, conditions it summarises); the first matching condition of a subject fills a cell,
#: a group of several gives its range.
HEADLINE_ROWS = (
    ("`ppm_detail`: the fitted PPM with its personal-detail layer", ("ppm_detail",)),
    ("`ppm`: the fitted PPM", ("ppm",)),
    ("`own_pinna`: its own pinna put back (the control)", ("own_pinna",)),
    ("`ppm_detail_hard`: the layered PPM from a defective scan", ("ppm_detail_hard",)),
    ("`ppm_hard`: the PPM from the defective scan", ("ppm_hard",)),
    ("`scan_hard`: the defective scan made watertight (screened Poisson)", ("scan_hard",)),
    ("`nricp_hard`: free-form NRICP from the defective scan", ("nricp_hard",)),
    ("`default_ppm`: the template ear, posed only", ("default_ppm",)),
    ("another subject's HRTFs (each of the other two)", ("other_",)),
    ("dummy heads (KU100, KEMAR)", ("ku100", "kemar")),
    ("measured listeners (two SONICOM, one LISTEN)", ("axd1", "axd2", "irc1003")),
)


def _cell(rows: list[dict]) -> str:
    if not rows:
        return "–"
    if len(rows) == 1:
        r = rows[0]
        share = "" if r["share_removed"] is None else f" ({_percent(r['share_removed'])})"
        return f"{r['delta_qe_pp']:+.2f} pp, {r['delta_pe_deg']:+.2f}°{share}"
    qe = sorted(r["delta_qe_pp"] for r in rows)
    pe = sorted(r["delta_pe_deg"] for r in rows)
    return f"{qe[0]:+.1f} to {qe[-1]:+.1f} pp, {pe[0]:+.1f} to {pe[-1]:+.1f}°"


def headline_markdown(rows: list[dict], not_solved: dict[str, dict[str, str]] | None = None) -> str:
    """The README's headline: per condition or alternative (:data:`HEADLINE_ROWS`) and subject, ΔQE and ΔPE by the
    paper's protocol and the share of the median non-individual penalty removed; "not built" where the pipeline
    refused a condition (``not_solved``: config evaluation.not_solved)."""
    subjects = list(dict.fromkeys(r["subject"] for r in rows))
    not_solved = not_solved or {}
    lines = ["| condition or alternative | " + " | ".join(subjects) + " |", "|---" * (len(subjects) + 1) + "|"]
    for label, names in HEADLINE_ROWS:
        cells = []
        for subject in subjects:
            chosen = [r for r in rows if r["subject"] == subject
                      and any(r["condition"] == n or (n.endswith("_") and r["condition"].startswith(n)) for n in names)]
            refused = [n for n in names if n in (not_solved.get(subject) or {})]
            cells.append("not built (the stitch refuses it)" if refused and not chosen else _cell(chosen))
        bold = names == ("ppm_detail",)
        lines.append(f"| {label} | " + " | ".join(f"**{c}**" if bold and c != "–" else c for c in cells) + " |")
    return "\n".join(lines)


def update_readme(readme: Path, table: str) -> None:
    """Rewrite the block between :data:`HEADLINE_BEGIN` and :data:`HEADLINE_END` of ``readme`` with ``table``."""
    from core.atomic import write_text_atomic  # noqa: PLC0415

    text = readme.read_text()
    if HEADLINE_BEGIN not in text or HEADLINE_END not in text:
        raise SystemExit(f"{readme}: no headline markers ({HEADLINE_BEGIN} ... {HEADLINE_END})")
    head, rest = text.split(HEADLINE_BEGIN, 1)
    tail = rest.split(HEADLINE_END, 1)[1]
    write_text_atomic(readme, f"{head}{HEADLINE_BEGIN}\n{table}\n{HEADLINE_END}{tail}")


def main(argv: list[str] | None = None) -> None:
    """Print the headline table from an evaluation's ranking.csv, or write it into the README (``--update``)."""
    import argparse  # noqa: PLC0415

    import yaml  # noqa: PLC0415

    root = Path(__file__).resolve().parents[1]
    parser = argparse.ArgumentParser(description="the README's headline table from an evaluation's ranking.csv")
    parser.add_argument("--ranking", type=Path, default=root / "evaluation" / "sonicom" / "ranking.csv")
    parser.add_argument("--config", type=Path, default=root / "config" / "paper_sonicom.yaml")
    parser.add_argument("--update", type=Path, default=None, metavar="README.md")
    args = parser.parse_args(argv)
    not_solved = (yaml.safe_load(args.config.read_text()).get("evaluation") or {}).get("not_solved") or {}
    table = headline_markdown(read_ranking_csv(args.ranking), not_solved)
    if args.update:
        update_readme(args.update, table)
    else:
        print(table)


if __name__ == "__main__":
    main()
