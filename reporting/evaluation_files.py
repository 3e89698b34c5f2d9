"""The evaluation's files: summary.csv and regions.csv (numbers to 3 decimals), the solved left-ear HRTFs and the
fixed defective scans, each written atomically; a SOFA file whose content is unchanged is left as it is, so that a
run that changes nothing leaves the checkout clean."""
from __future__ import annotations

import csv
import io
import os
import shutil
from pathlib import Path

from core.atomic import atomic_path, write_text_atomic

from .evaluation import COLUMNS
from .evaluation_regions import REGION_COLUMNS


def write_regions_csv(path: str | os.PathLike, regions: list[dict]) -> Path:
    """regions.csv (:data:`REGION_COLUMNS`), written atomically."""
    return write_csv(path, regions, REGION_COLUMNS)


def write_csv(path: str | os.PathLike, rows: list[dict], columns: tuple[str, ...]) -> Path:
    """`rows` as CSV with `columns` (numbers to 3 decimals, empty where a value does not apply), atomically."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({column: cell_text(row.get(column)) for column in columns})
    return write_text_atomic(path, buffer.getvalue())


def cell_text(value) -> str:
    if value is None or value == "":
        return ""
    if isinstance(value, float):
        return f"{value:.3f}"
    return str(value)


def write_summary_csv(path: str | os.PathLike, rows: list[dict]) -> Path:
    """summary.csv (columns :data:`COLUMNS`, empty where a value does not apply), written atomically."""
    return write_csv(path, rows, COLUMNS)


def read_summary_csv(path: str | os.PathLike) -> list[dict]:
    """summary.csv back as rows (numbers as floats, empty cells as None)."""
    rows = []
    with open(path, newline="") as handle:
        for raw in csv.DictReader(handle):
            row = {}
            for key, value in raw.items():
                if key in ("subject", "condition", "head_sha256", "solver"):
                    row[key] = value
                else:
                    row[key] = float(value) if value != "" else None
            rows.append(row)
    return rows


def left_hrtf_name(subject: str, condition: str) -> str:
    """File name of a condition's solved left-ear HRTFs in an evaluation folder's ``sofa/``."""
    return f"{subject}_{condition}_left_HRTF.sofa"


def left_hrtf_files(sofa_folder: str | os.PathLike, subject: str) -> dict[str, Path]:
    """Condition -> the solved left-ear HRTF file of ``subject`` in an evaluation's ``sofa/`` folder."""
    tail = left_hrtf_name("", "")[1:]  # "_left_HRTF.sofa"
    return {path.name[len(subject) + 1:-len(tail)]: path
            for path in sorted(Path(sofa_folder).glob(left_hrtf_name(subject, "*")))}


#: SOFA attributes that say when a file was written, not what it holds (sofar stamps them at every write).
SOFA_DATE_ATTRIBUTES = ("GLOBAL_DateCreated", "GLOBAL_DateModified")


#: Numbers of two SOFA files count as the same within this relative difference: the floating-point noise of turning
#: a grid into spherical positions on another machine (5.7e-14 deg seen on 360 deg), far below any solve's change.
SAME_NUMBERS_RTOL = 1e-12


def same_sofa_content(first: str | os.PathLike, second: str | os.PathLike) -> bool:
    """Whether two SOFA files hold the same data and metadata (every attribute equal, every variable equal within
    :data:`SAME_NUMBERS_RTOL` of its largest magnitude), apart from the dates of :data:`SOFA_DATE_ATTRIBUTES`."""
    import warnings  # noqa: PLC0415

    import numpy as np  # noqa: PLC0415
    import sofar  # noqa: PLC0415

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a, b = (sofar.read_sofa(str(path), verify=False, verbose=False) for path in (first, second))
    keys_a = {k for k in vars(a) if not k.startswith("_") and k not in SOFA_DATE_ATTRIBUTES}
    keys_b = {k for k in vars(b) if not k.startswith("_") and k not in SOFA_DATE_ATTRIBUTES}
    if keys_a != keys_b:
        return False
    for key in keys_a:
        x, y = getattr(a, key), getattr(b, key)
        if isinstance(x, str) or isinstance(y, str):
            if x != y:
                return False
        else:
            x, y = np.asarray(x), np.asarray(y)
            if x.shape != y.shape:
                return False
            scale = float(np.max(np.abs(x))) if x.size else 0.0
            if x.size and not np.all(np.abs(x - y) <= SAME_NUMBERS_RTOL * scale):
                return False
    return True


def committed_bytes(path: str | os.PathLike) -> bytes | None:
    """The bytes of ``path`` as the git checkout it lies in last committed it, or None (not in git, not committed,
    no git)."""
    import subprocess  # noqa: PLC0415

    path = Path(path).resolve()
    try:
        top = subprocess.run(["git", "-C", str(path.parent), "rev-parse", "--show-toplevel"], capture_output=True,
                             text=True, check=True).stdout.strip()
        relative = path.relative_to(Path(top).resolve()).as_posix()
        return subprocess.run(["git", "-C", top, "show", f"HEAD:{relative}"], capture_output=True,
                              check=True).stdout
    except (OSError, ValueError, subprocess.CalledProcessError):
        return None


def copy_sofa(hrtfs: dict[tuple[str, str], str], folder: str | os.PathLike) -> list[Path]:
    """The solved left-ear HRTFs (SimpleFreeFieldHRTF) as ``<subject>_<condition>_left_HRTF.sofa``. Where the
    checkout has committed a file with the same content (:func:`same_sofa_content`: sofar stamps every write with
    its date), the committed bytes are written back, so that a run that changes nothing leaves the checkout clean."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for (subject, condition), source in sorted(hrtfs.items()):
        target = folder / left_hrtf_name(subject, condition)
        kept = committed_bytes(target)
        with atomic_path(target) as tmp:
            if kept is not None:
                Path(tmp).write_bytes(kept)
                if same_sofa_content(tmp, source):
                    written.append(target)
                    continue
            shutil.copyfile(source, tmp)
        written.append(target)
    return written


def copy_hard_scans(scans: dict[str, str], folder: str | os.PathLike) -> list[Path]:
    """The fixed defective scan each subject's *_hard conditions started from, as ``<subject>_hard_scan.ply`` (mm,
    head frame): kept with the results, so that the conditions can be judged and redone from the same scan."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for subject, source in sorted(scans.items()):
        target = folder / f"{subject}_hard_scan.ply"
        with atomic_path(target) as tmp:
            shutil.copyfile(source, tmp)
        written.append(target)
    lines = ["# The fixed defective scans of the *_hard conditions", "",
             "Each subject's clean left crop with the defects of config `evaluation.hard_scan` (ppm/align/defects.py; "
             "mm, head frame), drawn once with the subject's own seed: the scan the conditions ppm_hard, "
             "ppm_detail_hard and nricp_hard were fitted to. Their distances are measured against the clean crop.", ""]
    lines += [f"- `{path.name}`" for path in written] or ["No *_hard condition in this evaluation."]
    written.append(write_text_atomic(folder / "README.md", "\n".join(lines) + "\n"))
    return written
