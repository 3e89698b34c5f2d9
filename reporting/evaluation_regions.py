"""Where the geometry of a condition's pinna differs from the scan: scan -> model distances per anatomical region
(reporting/pinna_regions.py) and, for each condition that misses its goal, the regions farthest from the scan (mm)."""
from __future__ import annotations

import os

import numpy as np

from .evaluation import GOALS, _paper_deltas, _within


#: Columns of regions.csv: scan -> model distances per anatomical region (reporting/pinna_regions.py).
REGION_COLUMNS = ("subject", "condition", "region", "points", "median_mm", "p95_mm", "over_1mm_percent")


def region_rows(results: str | os.PathLike, subjects: list[str], conditions: dict[str, list[str]],
                positions_mm: dict[str, dict[str, np.ndarray]]) -> list[dict]:
    """One row per subject, solved condition and pinna region (:data:`REGION_COLUMNS`), the regions labelled with
    each subject's landmark positions (mm) on its aligned PPM (``positions_mm[subject]``)."""
    from .pinna_regions import subject_regions  # noqa: PLC0415

    rows = []
    for subject in subjects:
        for condition, table in subject_regions(results, subject, conditions[subject], positions_mm[subject]).items():
            rows += [{"subject": subject, "condition": condition, **row} for row in table]
    return rows


SAME_SURFACE_MM = 0.1
"""A condition whose every region lies closer than this to the scan (p95, mm) has the scanned pinna itself
(own_pinna): a tenth of the 1 mm a pinna must be captured to, and half the median of the closest PPM fit (0.2 mm);
the cut-and-stitch path moves own-pinna scan points by up to 0.06 mm (P039's tragus and seam, p95)."""


def where_lines(rows: list[dict], regions: list[dict]) -> list[str]:
    """For every condition that misses its goal (by the paper's protocol where the subject has ``original``, else
    against the dataset's HRIRs): the two pinna regions farthest from the scan, against the whole scan's median
    (the paper traced its misses to the fossa triangularis and the cymba conchae); a condition whose pinna is the
    scanned one (``SAME_SURFACE_MM``) is said to miss for another reason than its shape."""
    from .pinna_regions import worst_regions  # noqa: PLC0415

    lines = []
    for row in rows:
        goal = GOALS.get(row["condition"])
        paper = _paper_deltas(row)
        qe, pe = paper if paper is not None else (row["delta_qe_pp"], row["delta_pe_deg"])
        if goal is None or _within(goal, qe, pe):
            continue
        table = [r for r in regions if r["subject"] == row["subject"] and r["condition"] == row["condition"]]
        if not table:
            continue
        protocol = ", paper's protocol" if paper is not None else ""
        head = f"{row['subject']} {row['condition']} (ΔQE {round(qe, 3):+.2f} pp, ΔPE {round(pe, 3):+.2f}°{protocol})"
        largest_p95 = max(round(r["p95_mm"], 3) for r in table)
        if largest_p95 < SAME_SURFACE_MM:
            lines.append(f"{head}: its pinna is the scanned one (every region's p95 at most {largest_p95:.3f} mm, "
                         f"under {SAME_SURFACE_MM} mm), so its miss is not the pinna's shape.")
            continue
        worst = worst_regions(table)
        # worded from the values as the CSV files keep them (3 decimals), so the text follows from the files
        parts = [f"the {r['region']} (median {round(r['median_mm'], 3):.2f} mm, {round(r['over_1mm_percent'], 3):.0f} % "
                 f"of its {r['points']} scan points beyond 1 mm)" for r in worst]
        lines.append(f"{head}: farthest from the scan are {' and '.join(parts)}; the whole scan's median is "
                     f"{round(row['distance_median_mm'], 3):.2f} mm.")
    return lines


def region_pivot(regions: list[dict], condition: str = "ppm") -> tuple[list[dict], tuple[str, ...]]:
    """Rows: regions; columns: subjects; values: median scan -> pinna distance (mm) of `condition`."""
    subjects = list(dict.fromkeys(r["subject"] for r in regions if r["condition"] == condition))
    table: dict[str, dict] = {}
    for r in regions:
        if r["condition"] == condition:
            table.setdefault(r["region"], {"region": r["region"]})[r["subject"]] = r["median_mm"]
    return list(table.values()), ("region", *subjects)
