"""The evaluation's pages: a self-contained HTML report and the folder's README (Markdown), from the summary rows,
the goal lines, the regions and the ranking."""
from __future__ import annotations

import html
import os
from pathlib import Path

from core.atomic import write_text_atomic

from .evaluation import COLUMNS, CONDITION_LABELS, goal_lines, paper_goal_lines
from .evaluation_files import cell_text
from .evaluation_regions import REGION_COLUMNS, region_pivot, where_lines


def _table_html(rows: list[dict], columns: tuple[str, ...]) -> str:
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(cell_text(r.get(c)))}</td>" for c in columns) + "</tr>"
                   for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _table_markdown(rows: list[dict], columns: tuple[str, ...]) -> str:
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell_text(r.get(c)) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


SHORT_COLUMNS = ("subject", "condition", "qe_percent", "pe_deg", "delta_qe_pp", "delta_pe_deg", "distance_median_mm",
                 "distance_p95_mm", "reverse_median_mm", "solve_cpu_hours")
#: The README's table by the paper's protocol (the reference row: the dataset's HRIRs heard with original's template).
PAPER_SHORT_COLUMNS = ("subject", "condition", "qe_paper_percent", "pe_paper_deg", "delta_qe_paper_pp",
                       "delta_pe_paper_deg", "distance_median_mm", "distance_p95_mm")

PAPER_PROTOCOL_TEXT = ("Per subject the unchanged head solved here (original) is the reference and the listener's "
                       "template, S is calibrated so that it reaches 8 % quadrant errors, and every condition's left "
                       "ear is predicted with them; the row reference is the dataset's own HRIRs heard with that "
                       "template.")


def _labels(rows: list[dict]) -> dict[str, str]:
    """:data:`CONDITION_LABELS` of the conditions the rows hold (all of them for rows that name none)."""
    present = {r.get("condition") for r in rows}
    return {c: t for c, t in CONDITION_LABELS.items() if c in present} or dict(CONDITION_LABELS)


def _paper_rows(rows: list[dict]) -> list[dict]:
    return [r for r in rows if r.get("qe_paper_percent") is not None]


def _regions_html(rows: list[dict], regions: list[dict] | None) -> list[str]:
    if not regions:
        return []
    pivot, columns = region_pivot(regions)
    return ["<h2>Where the geometry differs</h2>",
            "<ul>" + "".join(f"<li>{html.escape(line)}</li>" for line in where_lines(rows, regions)) + "</ul>",
            "<p>Median scan &rarr; PPM distance (mm) per region (each scan point in the region of its nearest "
            "landmark on the aligned PPM):</p>", _table_html(pivot, columns),
            "<details><summary>Every condition and region</summary>", _table_html(regions, REGION_COLUMNS),
            "</details>"]


def flat_settings(mapping: dict, prefix: str = "") -> list[tuple[str, object]]:
    """A nested config mapping as (dotted key, value) pairs, e.g. [("hrtf.step_store", "/x/steps")]."""
    pairs = []
    for key, value in mapping.items():
        name = f"{prefix}{key}"
        pairs.extend(flat_settings(value, f"{name}.") if isinstance(value, dict) else [(name, value)])
    return pairs


def _outside_note(outside_settings: list[str] | None) -> str:
    """What configfiles from outside the repository set (a clone lacks them), one sentence; empty if none."""
    if not outside_settings:
        return ""
    return ("Also given, from outside the repository (a clone has the repository's values instead): "
            + "; ".join(f"`{entry}`" for entry in outside_settings) + ".")


def not_solved_lines(not_solved: dict[str, dict[str, str]]) -> list[str]:
    """One line per condition the pipeline could not build for a subject (config evaluation.not_solved), with its
    reason: a failure is a result, so the report says it instead of leaving the row out silently."""
    return [f"{subject} `{condition}`: {reason}" for subject, failed in sorted(not_solved.items())
            for condition, reason in failed.items()]


def _ranking_html(ranking: list[dict] | None) -> list[str]:
    if not ranking:
        return []
    from .ranking import RANKING_COLUMNS, RANKING_TEXT  # noqa: PLC0415

    return ["<h2>What a personal HRTF buys: every condition and alternative, ranked</h2>",
            f"<p>{html.escape(RANKING_TEXT)}</p>", _table_html(ranking, RANKING_COLUMNS)]


def write_html(path: str | os.PathLike, rows: list[dict], figure6_path: Path, figure7_path: Path,
               frequency_note: str, configfiles: list[str], regions: list[dict] | None = None,
               outside_settings: list[str] | None = None, not_solved: list[str] | None = None,
               ranking: list[dict] | None = None) -> Path:
    """The evaluation's self-contained HTML page (figures embedded); ``not_solved``: lines of
    :func:`not_solved_lines`; ``ranking``: rows of :func:`reporting.ranking.ranking_rows`."""
    from .subject import STYLE, _image  # noqa: PLC0415

    goals = goal_lines(rows)
    paper_rows = _paper_rows(rows)
    paper = (["<h2>By the paper's protocol</h2>", f"<p>{html.escape(PAPER_PROTOCOL_TEXT)}</p>",
              "<ul>" + "".join(f"<li>{html.escape(g)}</li>" for g in paper_goal_lines(rows)) + "</ul>",
              _table_html(paper_rows, PAPER_SHORT_COLUMNS)] if paper_rows else [])
    parts = [f"<html><head><meta charset='utf-8'><title>PPM evaluation</title><style>{STYLE}</style></head><body>",
             "<h1>PPM evaluation: HRTFs of heads with the aligned PPM pinna vs the reference</h1>",
             "<p>Per subject the left ear of each condition's head was solved (NumCalc, " + html.escape(frequency_note)
             + ") on the reference SOFA's directions; the right ear is the reference's. baumgartner2014 with the "
             "reference as template; S calibrated so that the reference reaches 8 % quadrant errors.</p>",
             "<ul>" + "".join(f"<li><b>{html.escape(c)}</b>: {html.escape(t)}</li>" for c, t in _labels(rows).items())
             + "</ul>",
             *paper,
             *_ranking_html(ranking),
             "<h2>Goals against the dataset's HRIRs</h2><ul>" + "".join(f"<li>{html.escape(g)}</li>" for g in goals)
             + "</ul>",
             "<h2>Figure 7: predicted localisation</h2>", _image(figure7_path),
             "<h2>Figure 6: scan to pinna distances (the paper's scale; the same on 0-1.5 mm)</h2>", _image(figure6_path),
             *_regions_html(rows, regions),
             "<h2>Summary</h2>", _table_html(rows, COLUMNS),
             *(["<h2>Not solved</h2><ul>" + "".join(f"<li>{html.escape(line.replace('`', ''))}</li>"
                                                   for line in not_solved) + "</ul>"] if not_solved else []),
             f"<p>Configuration: {html.escape(' '.join(configfiles) or 'config/config.yaml')}. "
             f"{html.escape(_outside_note(outside_settings))}</p></body></html>"]
    return write_text_atomic(path, "\n".join(parts) + "\n")


def write_readme(path: str | os.PathLike, rows: list[dict], frequency_note: str, configfiles: list[str],
                 wall_clock_hours: float, regions: list[dict] | None = None,
                 outside_settings: list[str] | None = None, not_solved: list[str] | None = None,
                 ranking: list[dict] | None = None) -> Path:
    """The evaluation folder's README: what was run, by which command, at what cost, and the numbers (and the
    conditions that could not be built, ``not_solved``: lines of :func:`not_solved_lines`)."""
    command = "bash scripts/run.sh" + "".join(f" --configfile {c}" for c in configfiles)
    cpu = sum(r.get("solve_cpu_hours") or 0.0 for r in rows)
    outside = _outside_note(outside_settings)
    outside = f"{outside}\n" if outside else ""
    text = f"""# Evaluation: PPM heads vs reference HRTFs

Made by `{command}` (Snakemake; rules/evaluation.smk). Every number below is in `summary.csv`.
{outside}
- Conditions: {'; '.join(f'`{c}` = {t}' for c, t in _labels(rows).items())}.
- Solved: the left ear of each condition's head (NumCalc, {frequency_note}) on the reference SOFA's directions;
  the right ear is the reference's (rebuilt at the same frequencies). S is calibrated per subject so that the
  reference reaches 8 % quadrant errors; every condition is predicted with that S and the reference as template.
- Distances (mm): `distance_*` every scan point to the condition's pinna (the paper's one-sided Hausdorff
  distance); `reverse_*` every pinna vertex over the scanned region to the scan.
- Cost: {cpu:.2f} CPU hours of NumCalc (from the solver statuses kept with every step in `steps/`);
  {wall_clock_hours:.2f} h wall-clock of the jobs of the run that wrote this folder (Snakemake benchmark files;
  restored steps take seconds).
- `steps/` keeps every solved step with the SHA-256 of its project, and every head the pipeline built (`head.ply`):
  a fresh clone solves those very heads and restores the steps instead of solving (`head_sha256` in the summary).
  Beside each PPM head, `fit_landmarks.json` keeps the landmarks of its fit that label the scan's regions.

{_paper_markdown(rows)}{_ranking_markdown(ranking)}## Goals against the dataset's HRIRs

{chr(10).join(f'- {g}' for g in goal_lines(rows))}

## Results

{_table_markdown(rows, SHORT_COLUMNS)}
{_not_solved_markdown(not_solved)}{_regions_markdown(rows, regions)}
Files: `summary.csv`, `regions.csv`, `ranking.csv`, `report.html`, `figure6_distances.png`, `figure7_qe_pe.png`,
`sofa/<subject>_<condition>_left_HRTF.sofa` (the solved left ear, SimpleFreeFieldHRTF).
"""
    return write_text_atomic(path, text)


def _not_solved_markdown(not_solved: list[str] | None) -> str:
    if not not_solved:
        return ""
    lines = "\n".join(f"- {line}" for line in not_solved)
    return f"""
Not solved (config `evaluation.not_solved`): the pipeline could not build these heads.

{lines}
"""


def _ranking_markdown(ranking: list[dict] | None) -> str:
    if not ranking:
        return ""
    from .ranking import RANKING_TEXT, ranking_markdown  # noqa: PLC0415

    return f"""## What a personal HRTF buys: every condition and alternative, ranked

{RANKING_TEXT}

{ranking_markdown(ranking)}
"""


def _paper_markdown(rows: list[dict]) -> str:
    paper_rows = _paper_rows(rows)
    if not paper_rows:
        return ""
    lines = "\n".join(f"- {g}" for g in paper_goal_lines(rows))
    return f"""## By the paper's protocol

{PAPER_PROTOCOL_TEXT}

{lines}

{_table_markdown(paper_rows, PAPER_SHORT_COLUMNS)}

"""


def _regions_markdown(rows: list[dict], regions: list[dict] | None) -> str:
    if not regions:
        return ""
    pivot, columns = region_pivot(regions)
    lines = "\n".join(f"- {line}" for line in where_lines(rows, regions)) or "- every goal met"
    return f"""
## Where the geometry differs

Each scan point is put in the region of its nearest landmark on the subject's aligned PPM
(`ppm/data/landmark_regions.yaml`; the landmarks kept with the PPM head, `steps/<subject>/ppm/fit_landmarks.json`);
`regions.csv` has every condition and region.

{lines}

Median scan -> PPM distance (mm) per region:

{_table_markdown(pivot, columns)}
"""
