"""Dataset layout: one folder per subject holding its scans, head mesh and HRTFs; a subjects table
selects which of them a run takes."""
from __future__ import annotations

import csv
import os
from pathlib import Path

from .errors import PpmError


def read_subjects_table(path: str | os.PathLike) -> list[str]:
    """Subject names from a TSV whose header's first column is ``subject`` (lines starting with # are
    comments; further columns, such as notes, are kept for people and ignored here).

    Raises
    ------
    PpmError
        If the file is missing or empty, lacks the ``subject`` column, or names a subject twice.
    """
    path = Path(path)
    if not path.is_file():
        raise PpmError(f"{path}: no such subjects table; write a TSV with a 'subject' column or leave "
                       "config key subjects_table empty to run every subject of data_root")
    lines = [line for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]
    rows = list(csv.reader(lines, delimiter="\t"))
    if not rows or rows[0][0].strip() != "subject":
        raise PpmError(f"{path}: the first column of the header must be 'subject' (tab-separated)")
    subjects = [row[0].strip() for row in rows[1:] if row and row[0].strip()]
    if not subjects:
        raise PpmError(f"{path}: the subjects table lists no subject")
    twice = sorted({s for s in subjects if subjects.count(s) > 1})
    if twice:
        raise PpmError(f"{path}: subject(s) listed twice: {', '.join(twice)}")
    return subjects
