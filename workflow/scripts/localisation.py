"""Rule localisation: QE/PE of each solved condition's HRTFs (the PPM head, the controls) against the reference
listener (baumgartner2014)."""
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from amt_bridge.evaluation import compare_conditions, comparison_summary  # noqa: E402
from amt_bridge.plots import save_error_bars, save_prediction_matrices  # noqa: E402
from mesh2hrtf_io.frequency_sets import describe_set, frequencies_from_spec  # noqa: E402
from core.atomic import write_text_atomic  # noqa: E402

settings = snakemake.params.settings  # noqa: F821
out = snakemake.output  # noqa: F821
reference_frequencies = snakemake.params.reference_frequencies  # noqa: F821
conditions = {name: snakemake.input[name] for name in snakemake.params.conditions}  # noqa: F821
sensitivity, predictions = compare_conditions(snakemake.input.reference, conditions,  # noqa: F821
                                              settings["calibration_qe_percent"], settings["lateral_angles_deg"],
                                              reference_frequencies, snakemake.params.solved_ear)  # noqa: F821
save_error_bars(predictions, out.bars,
                title=f"{snakemake.wildcards.subject}: reference vs {', '.join(conditions)}")  # noqa: F821
save_prediction_matrices(predictions["reference"], out.reference_matrix, title="reference")
save_prediction_matrices(predictions["ppm"], out.ppm_matrix, title="PPM")
summary = comparison_summary(snakemake.input.reference, settings["calibration_qe_percent"], sensitivity,  # noqa: F821
                             predictions)
frequencies = frequencies_from_spec(snakemake.params.frequency_set)  # noqa: F821
summary["frequency_set"] = {"spec": snakemake.params.frequency_set, "description": describe_set(frequencies),  # noqa: F821
                            "frequencies_hz": frequencies.tolist(),
                            "reference_rebuilt_at_set": reference_frequencies is not None}
summary["solved_ear"] = snakemake.params.solved_ear or "both"  # noqa: F821
write_text_atomic(out.summary, json.dumps(summary, indent=2) + "\n")
