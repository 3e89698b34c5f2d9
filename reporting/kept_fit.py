"""The landmarks of the PPM fit that made a kept head, kept beside it in the step store.

The evaluation labels every scan point with the pinna region of its nearest landmark on the subject's aligned
PPM (:mod:`reporting.pinna_regions`). A kept PPM head (``<store>/<subject>/ppm/head.ply``) is solved and restored
byte for byte on every clone, but the alignment is rebuilt, and a rebuild on another machine is not the same fit
(P143's cymba conchae held 44 scan points by one fit and 50 by its rebuild). So the export keeps the landmark
positions of the fit that made the head as ``fit_landmarks.json`` beside it, tied to the head by its SHA-256;
the evaluation labels with them and then needs neither the template nor the alignment of that subject.

A head kept before this file existed gets the landmarks of the first rebuild that labels it (``"rebuilt":
true``): the fit that made it is lost, but from then on every clone labels the same way.
Millimetres, project frame (x front, y left, z up).
"""
from __future__ import annotations

import json
import logging
import os
from pathlib import Path

import numpy as np

from mesh2hrtf_io.step_store import HEAD_FILE, file_sha256, utc_now
from core.atomic import write_text_atomic

log = logging.getLogger(__name__)
FIT_LANDMARKS_FILE = "fit_landmarks.json"


def fit_landmarks_path(store: str | os.PathLike) -> Path:
    """Where a variant's store folder keeps the landmarks of the fit that made its head."""
    return Path(store) / FIT_LANDMARKS_FILE


def save_fit_landmarks(store: str | os.PathLike, pinna_path: str | os.PathLike, landmarks_path: str | os.PathLike,
                       rebuilt: bool = False) -> Path:
    """Keep the landmark positions (mm) of ``pinna_path`` (the aligned PPM, the template's topology; landmark
    vertices from ``landmarks_path``) beside the head kept in ``store``. ``rebuilt``: the fit is a rebuild, not
    the one that made the head. Raises ValueError when the store keeps no head to tie them to."""
    from .pinna_regions import landmark_positions_mm  # noqa: PLC0415

    head = Path(store) / HEAD_FILE
    if not head.is_file():
        raise ValueError(f"{store}: no {HEAD_FILE} is kept there, so there is no head to keep the fit's landmarks "
                         "for; export the head first (rule export_project keeps it)")
    positions = landmark_positions_mm(pinna_path, landmarks_path)
    record = {"head_sha256": file_sha256(head), "rebuilt": bool(rebuilt),
              "aligned_pinna_sha256": file_sha256(pinna_path), "from": str(pinna_path),
              "saved_utc": utc_now(),
              "landmarks_mm": {name: [round(float(v), 6) for v in xyz] for name, xyz in sorted(positions.items())}}
    target = fit_landmarks_path(store)
    write_text_atomic(target, json.dumps(record, indent=1) + "\n")
    return target


def kept_fit_landmarks(store: str | os.PathLike | None) -> dict[str, np.ndarray] | None:
    """Landmark name -> position (mm) of the fit kept with the store's head; None when none is kept, or when the
    kept head is not the one they were saved for (a replaced head: its fit is the new alignment's)."""
    if not store:
        return None
    path, head = fit_landmarks_path(store), Path(store) / HEAD_FILE
    if not path.is_file() or not head.is_file():
        return None
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
        positions = {str(name): np.asarray(xyz, np.float64) for name, xyz in record["landmarks_mm"].items()}
        head_sha = str(record["head_sha256"])
    except (ValueError, KeyError, TypeError) as error:
        raise ValueError(f"{path}: not a fit-landmarks file ({error}); delete it and run the evaluation again "
                         "(it is rebuilt from the alignment)") from error
    if head_sha != file_sha256(head):
        log.warning("%s was saved for another head than %s; the alignment's landmarks are used", path, head)
        return None
    if any(value.shape != (3,) or not np.all(np.isfinite(value)) for value in positions.values()):
        raise ValueError(f"{path}: every landmark must be three finite numbers (mm); delete the file and run the "
                         "evaluation again")
    return positions


def subject_fit_landmarks(store: str | os.PathLike | None, pinna_path: str | os.PathLike | None = None,
                          landmarks_path: str | os.PathLike | None = None) -> dict[str, np.ndarray]:
    """Landmark name -> position (mm) that label a subject's scan: those kept with its PPM head in ``store``, else
    those of the alignment ``pinna_path`` (template landmarks ``landmarks_path``), which are then kept with the
    head when the store keeps one (``rebuilt``: the fit that made it is not at hand)."""
    from .pinna_regions import landmark_positions_mm  # noqa: PLC0415

    kept = kept_fit_landmarks(store)
    if kept is not None:
        return kept
    if pinna_path is None or landmarks_path is None:
        raise ValueError(f"{store}: no fit landmarks are kept for its head; give the aligned PPM and the template's "
                         "landmarks.yaml")
    if store and (Path(store) / HEAD_FILE).is_file():
        log.info("keeping the landmarks of %s with the head in %s (a rebuilt fit)",
                 pinna_path, save_fit_landmarks(store, pinna_path, landmarks_path, rebuilt=True).parent)
    return landmark_positions_mm(pinna_path, landmarks_path)
