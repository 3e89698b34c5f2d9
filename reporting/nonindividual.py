"""Non-individual HRTF sets judged by the paper's protocol: what a listener would hear with someone else's HRTFs.

Per subject, the unchanged head solved here (``original``, left ear, completed with the dataset's right ear) is the
reference and the template, S is calibrated to 8 % QE on it (all of its directions), and each non-individual set is
predicted with that template and S, both of its ears being someone else's:

* another subject of the evaluation: that subject's ``original`` (left, solved here on the same grid with the same
  solver) completed with that subject's own dataset right ear; all directions kept;
* a measured set (a dummy head, a measured listener; ``evaluation.nonindividual`` in the config): its impulse
  responses are sampled exactly (DFT) at the evaluation's frequencies and rebuilt at the template's rate and length
  exactly as the solved heads are (:func:`mesh2hrtf_io.sparse_hrtf.rebuild_hrirs`), which resamples a set measured
  at another rate (44.1 kHz) to the template's 48 kHz; then each template direction takes the set's nearest
  direction within 2 deg (great circle), and the others are left out, from the set and from the template both
  (:func:`amt_bridge.hrtf_set.on_common_directions`). ΔQE and ΔPE are then taken against the template heard
  through itself on those same directions, so that a sparse grid is not counted as a penalty.

Frames: SOFA spherical (azimuth 0 front, +90 left; elevation +90 up; degrees); receiver 0 the left ear.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

#: Great-circle tolerance (deg) within which a measured set's direction stands for a template direction.
DIRECTION_TOLERANCE_DEG = 2.0


@dataclasses.dataclass(frozen=True)
class MeasuredSet:
    """A measured HRTF set from the config: ``name`` (the condition's name), ``path`` (SOFA SimpleFreeFieldHRIR or
    an ``.npz`` with ``hrir`` (M, 2, N) and ``grid`` (M, 3: azimuth, elevation in radians, radius)), ``kind``
    ("dummy head" or "listener") and, for an ``.npz``, its sampling rate (Hz), which such files do not store."""

    name: str
    path: Path
    kind: str
    sampling_rate_hz: float | None = None

    @classmethod
    def from_config(cls, entry: dict) -> MeasuredSet:
        return cls(str(entry["name"]), Path(entry["file"]), str(entry.get("kind", "listener")),
                   entry.get("sampling_rate_hz"))


def read_measured_set(measured: MeasuredSet):
    """The set as an :class:`amt_bridge.hrtf_set.HrirSet` (SOFA read by sofar; an ``.npz`` by numpy, its grid from
    radians to SOFA degrees)."""
    from amt_bridge.errors import AmtBridgeError  # noqa: PLC0415
    from amt_bridge.hrtf_set import HrirSet, read_hrtf_set  # noqa: PLC0415

    if measured.path.suffix.lower() != ".npz":
        return read_hrtf_set(measured.path)
    if not measured.path.is_file():
        raise AmtBridgeError(f"{measured.path}: no such file (config evaluation.nonindividual, set {measured.name!r})")
    if not measured.sampling_rate_hz:
        raise AmtBridgeError(f"{measured.path}: an .npz set stores no sampling rate; give sampling_rate_hz for set "
                             f"{measured.name!r} in config evaluation.nonindividual")
    with np.load(measured.path) as data:
        if "hrir" not in data or "grid" not in data:
            raise AmtBridgeError(f"{measured.path}: an .npz set needs arrays 'hrir' (M, 2, N) and 'grid' (M, 3: "
                                 "azimuth, elevation in radians, radius)")
        irs, grid = np.asarray(data["hrir"], np.float64), np.asarray(data["grid"], np.float64)
    return HrirSet(irs, float(measured.sampling_rate_hz), np.degrees(grid[:, 0]) % 360.0, np.degrees(grid[:, 1]),
                   source=str(measured.path))


def rebuilt_like(hrirs, frequencies_hz: np.ndarray, template):
    """``hrirs`` sampled at ``frequencies_hz`` (exact DFT at its own rate) and rebuilt at the template's rate and
    length, as the solved heads are."""
    from amt_bridge.hrtf_set import HrirSet  # noqa: PLC0415
    from mesh2hrtf_io.sparse_hrtf import rebuild_hrirs, sample_spectra  # noqa: PLC0415

    spectra = sample_spectra(hrirs.irs, hrirs.sampling_rate_hz, frequencies_hz)
    irs = rebuild_hrirs(spectra, frequencies_hz, template.sampling_rate_hz, template.irs.shape[-1], 0.0,
                        hrirs.source)
    return HrirSet(irs, template.sampling_rate_hz, hrirs.azimuth_deg, hrirs.elevation_deg,
                   source=f"{hrirs.source} at {len(frequencies_hz)} frequencies, {template.sampling_rate_hz:g} Hz")


def judged(candidate, template, sensitivity_db: float) -> dict:
    """QE/PE of ``candidate`` heard with ``template`` at S, on the template directions the candidate has within
    :data:`DIRECTION_TOLERANCE_DEG`, with the template's own QE/PE on those directions and the differences."""
    from amt_bridge.hrtf_set import on_common_directions  # noqa: PLC0415
    from amt_bridge.model import LocalisationModel  # noqa: PLC0415
    from reporting.paper_protocol import LATERAL_ANGLES_DEG  # noqa: PLC0415

    same_grid = (candidate.irs.shape[0] == template.irs.shape[0]
                 and np.allclose(candidate.azimuth_deg, template.azimuth_deg)
                 and np.allclose(candidate.elevation_deg, template.elevation_deg))
    if same_grid:  # direction by direction, as on one grid (the nearest search moved a SONICOM-grid set by 0.16 pp)
        target, kept = candidate, template
    else:
        target, kept = on_common_directions(candidate, template, DIRECTION_TOLERANCE_DEG)
    angles = list(LATERAL_ANGLES_DEG)
    prediction = LocalisationModel(target, kept, angles).predict(sensitivity_db).as_dict()
    own = LocalisationModel(kept, kept, angles).predict(sensitivity_db).as_dict()
    return {"qe_percent": prediction["qe_percent"], "pe_deg": prediction["pe_deg"],
            "delta_qe_pp": prediction["qe_percent"] - own["qe_percent"],
            "delta_pe_deg": prediction["pe_deg"] - own["pe_deg"], "directions": int(kept.irs.shape[0]),
            "template_qe_percent": own["qe_percent"], "template_pe_deg": own["pe_deg"]}


def nonindividual_rows(subjects: list[str], original_hrtfs: dict[str, str | os.PathLike],
                       dataset_hrirs: dict[str, str | os.PathLike], measured: list[MeasuredSet]) -> list[dict]:
    """One row per subject and non-individual set (``other_<subject>`` for another subject's ``original``, the
    measured set's name otherwise) with ``subject``, ``condition``, ``kind``, ``directions``, QE/PE and ΔQE/ΔPE by
    the paper's protocol (see the module's docstring), the subject's S in ``sensitivity_db``."""
    from reporting.paper_protocol import protocol_calibration, protocol_template  # noqa: PLC0415

    solved = [s for s in subjects if s in original_hrtfs]
    frequencies, own_sets = {}, {}
    for subject in solved:
        frequencies[subject], _, own_sets[subject] = protocol_template(original_hrtfs[subject], dataset_hrirs[subject])
    measured_sets = {m.name: (m, read_measured_set(m)) for m in measured}
    rows = []
    for subject in solved:
        template = own_sets[subject]
        _, sensitivity = protocol_calibration(template)
        candidates = [(f"other_{other}", "dataset subject", own_sets[other]) for other in solved
                      if other != subject and np.allclose(frequencies[other], frequencies[subject])]
        candidates += [(name, m.kind, rebuilt_like(hrirs, frequencies[subject], template))
                       for name, (m, hrirs) in measured_sets.items()]
        for name, kind, candidate in candidates:
            rows.append({"subject": subject, "condition": name, "kind": kind, "sensitivity_db": sensitivity,
                         **judged(candidate, template, sensitivity)})
    return rows
