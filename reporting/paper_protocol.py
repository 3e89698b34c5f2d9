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


def paper_protocol(reference_hrtf: str | os.PathLike, conditions: dict[str, str | os.PathLike],
                   dataset_hrir: str | os.PathLike) -> dict:
    """QE/PE of each condition (left-ear HRTF SOFA files, by name) with ``reference_hrtf`` (a left-ear SOFA)
    as reference and template, completed with the right ear of ``dataset_hrir`` (the dataset's SOFA, sampled
    at the solved frequencies and rebuilt). Returns {"sensitivity_db", "reference": prediction, name: prediction},
    each prediction with ``qe_percent``, ``pe_deg`` and the rest of
    :meth:`amt_bridge.performance.Prediction.as_dict`."""
    import sofar  # noqa: PLC0415

    from amt_bridge.hrtf_set import read_hrtf_set, read_one_ear_completed, resampled_at  # noqa: PLC0415
    from amt_bridge.model import LocalisationModel  # noqa: PLC0415

    frequencies = np.asarray(sofar.read_sofa(str(reference_hrtf), verify=False).N)
    dataset = resampled_at(read_hrtf_set(dataset_hrir), frequencies)
    template = read_one_ear_completed(reference_hrtf, "left", dataset)
    model = LocalisationModel(template, template, list(LATERAL_ANGLES_DEG))
    sensitivity = model.calibrate(REFERENCE_QE_PERCENT, closest=True)
    result = {"sensitivity_db": sensitivity, "reference": model.predict(sensitivity).as_dict()}
    for name, path in conditions.items():
        condition = read_one_ear_completed(path, "left", dataset)
        result[name] = LocalisationModel(condition, template, list(LATERAL_ANGLES_DEG)).predict(sensitivity).as_dict()
    return result
