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


def _plane_qe_pe(prediction) -> list[dict]:
    """Per sagittal plane: lateral angle (deg), QE (%), PE (deg)."""
    return [{"lateral_deg": plane.lateral_deg, "qe_percent": float(plane.performance.qe_percent),
             "pe_deg": float(plane.performance.pe_deg)} for plane in prediction.planes]


def both_ears_protocol(reference, personal, directions=None, tolerance_deg: float = 0.5) -> dict:
    """The paper's protocol for a listener whose two ears are both solved: ``reference`` (an
    :class:`amt_bridge.hrtf_set.HrirSet`, the listener's head as scanned, solved exactly as ``personal``) is the
    template, S is calibrated so that it gives :data:`REFERENCE_QE_PERCENT` heard through itself, and ``personal`` is
    heard with it in the three sagittal planes of :data:`LATERAL_ANGLES_DEG` (-20 deg: the right hemisphere, 0: the
    median plane, +20: the left). As in AMT's baumgartner2014, each ear's similarity index is weighted by its binaural
    weight, 1 / (1 + exp(-lateral / 13 deg)) for the left ear and its complement for the right, before the response
    probabilities are formed; QE and PE are the planes' mean. Each ear alone: ``personal``'s one ear with the
    reference's other. ``directions`` (an HrirSet, e.g. the dataset's) narrows both sets to its directions first (each
    must be there within ``tolerance_deg``).

    Returns {"sensitivity_db", "directions", "reference", "both", "left", "right"}, each prediction as
    {"qe_percent", "pe_deg", "delta_qe_pp", "delta_pe_deg", "planes": [{lateral_deg, qe_percent, pe_deg}, ...]}."""
    import dataclasses  # noqa: PLC0415

    from amt_bridge.errors import AmtBridgeError  # noqa: PLC0415
    from amt_bridge.hrtf_set import on_common_directions  # noqa: PLC0415
    from amt_bridge.model import LocalisationModel  # noqa: PLC0415

    if directions is not None:
        narrowed = []
        for hrirs in (reference, personal):
            on, _ = on_common_directions(hrirs, directions, tolerance_deg)
            if on.irs.shape[0] != directions.irs.shape[0]:
                raise AmtBridgeError(f"{hrirs.source} has only {on.irs.shape[0]} of the {directions.irs.shape[0]} "
                                     f"directions of {directions.source} within {tolerance_deg} deg; solve it on a grid "
                                     "that contains them (config listener.dataset_grid)")
            narrowed.append(on)
        reference, personal = narrowed
    else:
        personal, reference = on_common_directions(personal, reference, tolerance_deg)
    model, sensitivity = protocol_calibration(reference)
    base = model.predict(sensitivity)

    def judged(target) -> dict:
        prediction = LocalisationModel(target, reference, list(LATERAL_ANGLES_DEG)).predict(sensitivity)
        return {"qe_percent": prediction.qe, "pe_deg": prediction.pe, "delta_qe_pp": prediction.qe - base.qe,
                "delta_pe_deg": prediction.pe - base.pe, "planes": _plane_qe_pe(prediction)}

    result = {"sensitivity_db": float(sensitivity), "directions": int(reference.irs.shape[0]),
              "reference": {"qe_percent": base.qe, "pe_deg": base.pe, "delta_qe_pp": 0.0, "delta_pe_deg": 0.0,
                            "planes": _plane_qe_pe(base)},
              "both": judged(personal)}
    for index, side in enumerate(("left", "right")):
        irs = reference.irs.copy()
        irs[:, index] = personal.irs[:, index]
        result[side] = judged(dataclasses.replace(reference, irs=irs, source=f"{personal.source}, {side} ear only"))
    return result
