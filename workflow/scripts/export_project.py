"""Rules export_project and export_band_project: a Mesh2HRTF project (NumCalc input) from a closed head mesh in
millimetres; a PPM head built now is kept in the step store with the landmarks of its fit (reporting.kept_fit), a band
mesh with its source faces."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from mesh2hrtf_io.hrtf_job import export_head_project  # noqa: E402

inputs, params = snakemake.input, snakemake.params  # noqa: F821
export_head_project(inputs.head, snakemake.output.project, params.settings,  # noqa: F821
                    inputs.get("grid_sofa"), params.title, params.head_store, inputs.get("sources"))
if params.head_store and inputs.get("sources"):  # a band mesh: its source faces are kept beside its head
    from mesh2hrtf_io.step_store import save_band_sources  # noqa: E402

    save_band_sources(inputs.sources, params.head_store)
if params.head_store and "fit_aligned" in inputs.keys():
    from reporting.kept_fit import save_fit_landmarks  # noqa: E402

    save_fit_landmarks(params.head_store, inputs.fit_aligned, inputs.fit_landmarks)
