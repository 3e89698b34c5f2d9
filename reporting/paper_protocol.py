"""The paper's protocol: the HRTFs computed from the ground-truth head (here ``original``, the unchanged head solved
by this pipeline) are the reference and the listener's template; S is calibrated to 8 % QE on them, and every
condition is predicted with that template and S. Left ears solved, right ear from the dataset's reference HRIRs
(rebuilt at the solved frequencies), as in the evaluation.
"""
from __future__ import annotations

import os

import numpy as np

#: Lateral angles (deg) of the sagittal planes baumgartner2014 averages, as in the evaluation.
LATERAL_ANGLES_DEG = (-20.0, 0.0, 20.0)
REFERENCE_QE_PERCENT = 8.0
#: The columns the paper's protocol adds to an evaluation's summary.csv (empty where a subject has no ``original``).
PAPER_COLUMNS = ("qe_paper_percent", "pe_paper_deg", "delta_qe_paper_pp", "delta_pe_paper_deg")


def protocol_template(reference_hrtf: str | os.PathLike, dataset_hrir: str | os.PathLike):
    """(frequencies (Hz), the dataset's set sampled at them and rebuilt, the template): ``reference_hrtf``'s left ear
    (a one-ear SOFA) completed with the right ear of ``dataset_hrir``, as the paper's protocol hears every set."""
    import sofar  # noqa: PLC0415

    from amt_bridge.hrtf_set import read_hrtf_set, read_one_ear_completed, resampled_at  # noqa: PLC0415

    frequencies = np.asarray(sofar.read_sofa(str(reference_hrtf), verify=False, verbose=False).N)
    dataset = resampled_at(read_hrtf_set(dataset_hrir), frequencies)
    return frequencies, dataset, read_one_ear_completed(reference_hrtf, "left", dataset)


def protocol_calibration(template):
    """(the model of ``template`` heard through itself, S in dB at which it gives :data:`REFERENCE_QE_PERCENT`; the
    closest in the bracket where none does)."""
    from amt_bridge.model import LocalisationModel  # noqa: PLC0415

    model = LocalisationModel(template, template, list(LATERAL_ANGLES_DEG))
    return model, model.calibrate(REFERENCE_QE_PERCENT, closest=True)


def paper_protocol(reference_hrtf: str | os.PathLike, conditions: dict[str, str | os.PathLike],
                   dataset_hrir: str | os.PathLike) -> dict:
    """QE/PE of each condition (left-ear HRTF SOFA files, by name) with ``reference_hrtf`` (a left-ear SOFA)
    as reference and template, completed with the right ear of ``dataset_hrir`` (the dataset's SOFA, sampled
    at the solved frequencies and rebuilt). Returns {"sensitivity_db", "reference": prediction, name: prediction},
    each prediction with ``qe_percent``, ``pe_deg`` and the rest of
    :meth:`amt_bridge.performance.Prediction.as_dict`."""
    from amt_bridge.hrtf_set import read_one_ear_completed  # noqa: PLC0415
    from amt_bridge.model import LocalisationModel  # noqa: PLC0415

    _, dataset, template = protocol_template(reference_hrtf, dataset_hrir)
    model, sensitivity = protocol_calibration(template)
    result = {"sensitivity_db": sensitivity, "reference": model.predict(sensitivity).as_dict()}
    for name, path in conditions.items():
        condition = dataset if name == "dataset" else read_one_ear_completed(path, "left", dataset)
        result[name] = LocalisationModel(condition, template, list(LATERAL_ANGLES_DEG)).predict(sensitivity).as_dict()
    return result


def with_paper_columns(rows: list[dict], hrtfs: dict[tuple[str, str], str | os.PathLike],
                       dataset_hrirs: dict[str, str | os.PathLike]) -> list[dict]:
    """``rows`` of an evaluation's summary (one per subject and condition, the dataset's ``reference`` included)
    with :data:`PAPER_COLUMNS` filled for every subject that has ``original`` among ``hrtfs`` ((subject,
    condition) -> left-ear HRTF SOFA): QE (%) and PE (deg) by the paper's protocol and their differences from
    ``original``'s. The ``reference`` row is the dataset's HRIRs heard with ``original`` as template."""
    out = [dict(row) for row in rows]
    for subject in dict.fromkeys(row["subject"] for row in out):
        if (subject, "original") not in hrtfs:
            continue
        named = {row["condition"]: ("dataset" if row["condition"] == "reference" else row["condition"])
                 for row in out if row["subject"] == subject and row["condition"] != "original"}
        conditions = {name: hrtfs.get((subject, condition)) for condition, name in named.items()}
        missing = [c for c, name in named.items() if name != "dataset" and conditions[name] is None]
        if missing:
            raise ValueError(f"{subject}: no solved HRTF of {', '.join(missing)} for the paper's protocol")
        result = paper_protocol(hrtfs[subject, "original"], conditions, dataset_hrirs[subject])
        base = result["reference"]
        for row in out:
            if row["subject"] != subject:
                continue
            prediction = base if row["condition"] == "original" else result[named[row["condition"]]]
            row.update(qe_paper_percent=prediction["qe_percent"], pe_paper_deg=prediction["pe_deg"],
                       delta_qe_paper_pp=prediction["qe_percent"] - base["qe_percent"],
                       delta_pe_paper_deg=prediction["pe_deg"] - base["pe_deg"])
    return out
