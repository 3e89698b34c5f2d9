# Config validation, wildcard constraints and input functions (no rules here).
import os
from pathlib import Path
from types import SimpleNamespace

import yaml
from snakemake.utils import validate

validate(config, "../config/schema.yaml")

DEMO = not config["data_root"]


def _demo_overrides():
    """With no dataset, the demo's hrtf keys and remeshing bands replace the general ones (and are checked)."""
    config["hrtf"].update(config["demo"]["hrtf"])
    config["stitch"]["bands"] = config["demo"]["bands"]
    validate(config, "../config/schema.yaml")


def _subjects_of(data_root: Path) -> list[str]:
    """Subjects of a dataset folder: every <subject>/pinna_left_crop.ply, narrowed by config subjects_table."""
    found = sorted(p.name for p in data_root.iterdir() if (p / "pinna_left_crop.ply").is_file())
    if not found:
        raise ValueError(
            f"config key data_root={config['data_root']!r}: no <subject>/pinna_left_crop.ply under it; "
            "point data_root to a dataset folder or leave it empty for the demo"
        )
    if not config["subjects_table"]:
        return found
    from ppm.dataset import read_subjects_table

    wanted = read_subjects_table(config["subjects_table"])
    unknown = [s for s in wanted if s not in found]
    if unknown:
        raise ValueError(
            f"config key subjects_table={config['subjects_table']!r}: subject(s) {', '.join(unknown)} have no "
            f"pinna_left_crop.ply under data_root={config['data_root']!r}; known: {', '.join(found)}"
        )
    return wanted


if DEMO:
    _demo_overrides()
    DATA_ROOT = Path("results/demo_data")
    SUBJECTS = [f"demo{i:02d}" for i in range(1, config["demo"]["subjects"] + 1)]
else:
    DATA_ROOT = Path(config["data_root"])
    if not DATA_ROOT.is_dir():
        raise ValueError(
            f"config key data_root={config['data_root']!r}: no such folder; give a dataset folder of "
            "<subject>/pinna_left_crop.ply, or leave data_root empty for the demo"
        )
    SUBJECTS = _subjects_of(DATA_ROOT)


def _check_embedded_backend():
    """An explicit hrtf.embedded_device (opencl, cuda) must have passed its probe on this machine before any job
    starts (mesh2hrtf_io/backends.py; the verdict is cached, so only the first run of a machine probes)."""
    hrtf = config["hrtf"]
    device = hrtf.get("embedded_device", "auto")
    if hrtf["enabled"] and hrtf["solver"] == "embedded" and device in ("opencl", "cuda"):
        from mesh2hrtf_io.backends import choose_backend

        choose_backend(device)  # raises with the probe's failure and the setting to change


_check_embedded_backend()


wildcard_constraints:
    subject="|".join(SUBJECTS),
    variant="reference|original|ppm|own_pinna|default_ppm",
    control="own_pinna|default_ppm",
    source="[12]",
    first="[0-9]+",
    last="[0-9]+",


def demo_seed(wildcards) -> int:
    """Random seed of a demo subject: config demo.seed for demo01, + 1 for each next one."""
    return config["demo"]["seed"] + SUBJECTS.index(wildcards.subject)


def align_template(wildcards) -> str:
    """The template a subject is fitted with: built without that subject from the dataset, or, for the
    demo (whose ears are made by the packaged PPM), the packaged template."""
    if DEMO:
        from ppm.template.store import default_template_dir

        return str(default_template_dir() / "template_left.ply")
    return f"results/templates/without_{wildcards.subject}/template_left.ply"


def template_params():
    """Settings of the template build, from config/template."""
    return config["template"]


HRTF_VARIANTS = ("reference", "original", "ppm", "own_pinna", "default_ppm")
CONTROLS = ("own_pinna", "default_ppm")
from reporting.evaluation import flat_settings
from mesh2hrtf_io.step_store import stored_head
from reporting.solve_plan import BUILT_HEADS  # ppm and the controls: heads kept in the step store beside their steps


def evaluation_conditions(subject: str) -> list[str]:
    """The solved conditions of a subject's evaluation (config evaluation.conditions); a control only for the
    subjects of evaluation.<control>_subjects (original_subjects, own_pinna_subjects, default_ppm_subjects), all
    when that list is empty."""
    evaluation = config["evaluation"]

    def chosen(condition: str) -> bool:
        subjects = evaluation.get(f"{condition}_subjects") or []  # ppm has no such list: always
        return not subjects or subject in subjects

    return [c for c in evaluation["conditions"] if chosen(c)]


def control_pinna(wildcards) -> str:
    """The pinna a control condition stitches onto the head (mm): the head's own pinna region (own_pinna) or
    the template placed by the global pose only (default_ppm)."""
    if wildcards.control == "own_pinna":
        return f"results/{wildcards.subject}/controls/own_pinna/pinna.ply"
    return f"results/{wildcards.subject}/controls/default_ppm/align/aligned_pinna.ply"


def hrtf_frequencies():
    """Frequencies (Hz) of the HRTF projects, from config hrtf.frequencies_hz (any form of
    mesh2hrtf_io/data/frequency_sets.yaml)."""
    from mesh2hrtf_io.frequency_sets import frequencies_from_spec

    return frequencies_from_spec(config["hrtf"]["frequencies_hz"])


def head_mesh_of(subject: str, variant: str) -> str:
    """The head mesh (mm) whose HRTFs a subject's variant stands for ("original": the reference head itself, solved
    here as an evaluation condition, so that the solved conditions are also compared with this pipeline's own
    solve of the unchanged head). A head the pipeline builds (BUILT_HEADS) is taken from the step store when it
    keeps one (``head.ply``, saved at the export): its stored steps were solved for exactly that mesh, which a
    rebuild on another machine does not reproduce bit for bit."""
    if variant in ("reference", "original"):
        return str(DATA_ROOT / subject / config["hrtf"]["reference_head"])
    if variant not in BUILT_HEADS:
        raise ValueError(f"unknown HRTF variant {variant!r}; known: {HRTF_VARIANTS}")
    kept = stored_head(store_of(subject, variant))
    if kept is not None:
        return str(kept)
    if variant == "ppm":
        return f"results/{subject}/remesh/head.ply"
    return f"results/{subject}/controls/{variant}/head.ply"


def hrtf_head_mesh(wildcards):
    """Input function: the head mesh of {subject} and {variant}."""
    return head_mesh_of(wildcards.subject, wildcards.variant)


def given_reference_sofa(subject: str) -> Path:
    """Where the dataset keeps a subject's reference HRIRs (config localisation.reference_sofa; may be absent)."""
    return DATA_ROOT / subject / config["localisation"]["reference_sofa"]


def hrtf_export_inputs(wildcards) -> dict:
    """The head mesh and, with config hrtf.grid = reference_sofa, the reference SOFA whose directions the
    project is solved at (so that solved and reference ears combine direction by direction)."""
    inputs = {"head": hrtf_head_mesh(wildcards)}
    store = store_of(wildcards.subject, wildcards.variant)
    if wildcards.variant == "ppm" and store and stored_head(store) is None:
        # a PPM head built now and kept at the export: the landmarks of its fit are kept with it (reporting.kept_fit)
        inputs.update(fit_landmark_inputs(wildcards.subject, prefix="fit"))
    if config["hrtf"]["grid"] == "reference_sofa":
        given = given_reference_sofa(wildcards.subject)
        if not given.is_file():
            raise ValueError(f"config hrtf.grid=reference_sofa: {given} is missing; give the reference HRIRs or use "
                             "hrtf.grid: sagittal")
        inputs["grid_sofa"] = str(given)
    return inputs


def store_of(subject: str, variant: str) -> str | None:
    """Where solved steps of a subject's variant are kept (config hrtf.step_store), or None."""
    folder = config["hrtf"]["step_store"]
    return str(Path(folder) / subject / variant) if folder else None


def step_store(wildcards):
    """Param function: the step store of {subject} and {variant}, or None."""
    return store_of(wildcards.subject, wildcards.variant)


def hrtf_sources():
    """Source folders of a project: source_1 (left ear) and, for both ears, source_2 (right ear)."""
    return ["1", "2"] if config["hrtf"]["ears"] == "both" else ["1"]


def steps_of(subject: str, variant: str) -> list[str]:
    """The status files of a subject's variant's solve: every NumCalc step job, or the subject's embedded job."""
    base = f"results/{subject}/hrtf/{variant}/steps"
    if config["hrtf"]["solver"] == "embedded":
        return [f"results/{subject}/hrtf/embedded.json"]
    n_steps, per_job = len(hrtf_frequencies()), config["hrtf"]["steps_per_job"]
    ranges = [(k, min(k + per_job - 1, n_steps)) for k in range(1, n_steps + 1, per_job)]
    return [f"{base}/source_{s}/steps_{a}-{b}.json" for s in hrtf_sources() for a, b in ranges]


def solved_steps(wildcards):
    """Input function of collect_sofa: the status files of {subject} and {variant}'s solve."""
    return steps_of(wildcards.subject, wildcards.variant)


def _numcalc_job_costs(wildcards, input):
    """Predicted costs of the steps of one NumCalc job (mesh2hrtf_io.numcalc_cost), or None before the export
    (dry run) or without a NumCalc binary."""
    from mesh2hrtf_io.numcalc import NumCalcError, find_numcalc
    from mesh2hrtf_io.numcalc_cost import project_step_costs

    if not (Path(input.project) / "parameters.json").is_file():
        return None
    try:
        costs = project_step_costs(input.project, find_numcalc(config["hrtf"]["numcalc"] or None))
    except (NumCalcError, ValueError, OSError):
        return None
    return costs[int(wildcards.first) - 1 : int(wildcards.last)]


def _measured(rule: str, key: str):
    """Resource function: request ``key`` (mem_mb, runtime in minutes) of a rule from its measured peak
    (workflow/resources.yaml, reporting/resources.py), +50 % per retry."""
    from reporting.resources import requests

    base = requests(rule)[key]
    return lambda wildcards, attempt: int(base * (1 + 0.5 * (attempt - 1)))


def measured_mem_mb(rule: str):
    """Memory request (MB) of a rule from its measured peak, +50 % per retry."""
    return _measured(rule, "mem_mb")


def measured_runtime(rule: str):
    """Wall-clock request (minutes) of a rule from its measured peak, +50 % per retry."""
    return _measured(rule, "runtime")


def numcalc_step_mem_mb(wildcards, input, attempt):
    """Memory of a NumCalc job (its largest step) from `NumCalc -estimate_ram`, +20 %, +50 % per retry."""
    costs = _numcalc_job_costs(wildcards, input)
    gigabytes = max(c.memory_gb for c in costs) if costs else 2.0
    return int(1024 * max(gigabytes, 0.25) * 1.2 * (1 + 0.5 * (attempt - 1)))


def numcalc_step_runtime_min(wildcards, input, attempt):
    """Wall-clock limit of a NumCalc job (minutes): its predicted steps x 3 (+50 % per retry), at least 10;
    config hrtf.step_runtime_min per step when no prediction can be made. x 3, not x 2: the steps below ~1 kHz,
    where NumCalc's memory estimate jumps (12.7 GB against 2.6 GB on P067's own_pinna head), took up to 1.9 x
    their prediction here (1148 and 1041 s against 646 s; mid-band steps 0.7-1.7 x)."""
    costs = _numcalc_job_costs(wildcards, input)
    if not costs:
        return int(config["hrtf"]["step_runtime_min"] * (int(wildcards.last) - int(wildcards.first) + 1))
    return max(10, int(round(3 * sum(c.seconds for c in costs) / 60 * (1 + 0.5 * (attempt - 1)))))


def solved_variants(subject: str) -> list[str]:
    """The heads whose HRTFs are solved for a subject: the reference head when the dataset has no reference
    HRIRs (config localisation.reference_sofa), and every evaluation condition (the PPM head first)."""
    given = given_reference_sofa(subject).is_file()
    return ([] if given else ["reference"]) + evaluation_conditions(subject)


def _embedded_costs(projects) -> list | None:
    """(dense cost model estimate, number of frequencies) of each exported project, or None before the export
    (dry run)."""
    from mesh2hrtf_io.bem import estimate_cost
    from mesh2hrtf_io.project_reader import read_project

    backend = "cuda" if embedded_on_gpu() else "numba"
    costs = []
    for project in projects:
        if not (Path(project) / "parameters.json").is_file():
            return None
        solved = read_project(project)
        costs.append((estimate_cost(len(solved.vertices_m), len(solved.faces), len(solved.evaluation_points_m),
                                    backend=backend), len(solved.frequencies_hz)))
    return costs


def embedded_on_gpu() -> bool:
    """Whether the embedded solver is asked to run on a GPU (hrtf.embedded_device: cuda)."""
    return config["hrtf"].get("embedded_device", "auto") == "cuda"


def embedded_gpus(wildcards) -> int:
    """GPUs an embedded-solver job asks a cluster for: 1 with hrtf.embedded_device cuda, else 0."""
    return 1 if embedded_on_gpu() else 0


def embedded_runtime_min(wildcards, input, attempt):
    """Wall-clock request (minutes) of a subject's embedded-solver job from the dense cost model: 3 x the predicted
    seconds of every frequency of every head + 5 min of numba compilation (at least 10 min); +50 % per retry. Before
    the export (dry run): config hrtf.step_runtime_min per frequency."""
    costs = _embedded_costs(input.projects)
    if costs is None:
        return int(config["hrtf"]["step_runtime_min"] * len(hrtf_frequencies()))
    seconds = 300.0 + sum(3.0 * cost.seconds_per_frequency * n for cost, n in costs)
    return max(10, int(round(seconds / 60.0 * (1 + 0.5 * (attempt - 1)))))


def embedded_mem_mb(wildcards, input):
    """Memory of the embedded solver (its largest head, one at a time) from its dense-operator model; on a GPU the
    dense system lives in the GPU's memory (checked there before the first frequency) and the host needs little."""
    if embedded_on_gpu():
        return 8192
    costs = _embedded_costs(input.projects)
    if costs is None:
        return 4096
    return int(1024 * max(cost.memory_gb_per_frequency for cost, _ in costs) * 1.3) + 1500


def reference_sofa(wildcards):
    """The reference listener's HRIRs: the dataset's own SOFA file when present, else computed."""
    given = given_reference_sofa(wildcards.subject)
    if given.is_file():
        return str(given)
    return f"results/{wildcards.subject}/hrtf/reference/HRIR.sofa"


def reference_frequencies(wildcards):
    """The sparse set the PPM head was solved at, when the reference is the dataset's own (full) HRIR file:
    the localisation rule samples and rebuilds the reference there, like with like. None otherwise."""
    from mesh2hrtf_io.frequency_sets import is_linear_grid

    frequencies = hrtf_frequencies()
    if is_linear_grid(frequencies) or not reference_sofa(wildcards).startswith(str(DATA_ROOT)):
        return None
    return frequencies.tolist()


def localisation_inputs(wildcards) -> dict:
    """The reference HRIRs and the HRIRs of every solved condition of the subject (by condition name)."""
    inputs = {"reference": reference_sofa(wildcards)}
    for condition in evaluation_conditions(wildcards.subject):
        inputs[condition] = f"results/{wildcards.subject}/hrtf/{condition}/HRIR.sofa"
    return inputs


EVALUATION_FOLDER = config["evaluation"]["folder"]
#: How the evaluation was configured, for its README: the configfiles given on the command line that lie in the
#: working directory (relative; Snakemake keeps them absolute), and what each one outside it set (a clone does not
#: have such a file, so its settings are spelled out: "path: key = value, ...").
_INSIDE = {path: Path(path).resolve().is_relative_to(Path.cwd().resolve()) for path in workflow.overwrite_configfiles}
EVALUATION_CONFIGFILES = [os.path.relpath(path) for path, inside in _INSIDE.items() if inside]
EVALUATION_OUTSIDE_SETTINGS = [f"{path}: " + ", ".join(f"{key} = {value}" for key, value in
                                                        flat_settings(yaml.safe_load(Path(path).read_text()) or {}))
                               for path, inside in _INSIDE.items() if not inside]


def fit_landmark_inputs(subject: str, prefix: str | None = None) -> dict:
    """The landmarks on a subject's aligned PPM that label its scan points by region: the kept fit's
    (``fit_landmarks.json`` beside the kept PPM head, :mod:`reporting.kept_fit`), else the alignment and the
    template's landmarks.yaml. Keys start with ``prefix`` (default: the subject)."""
    from reporting.kept_fit import fit_landmarks_path, kept_fit_landmarks

    prefix = subject if prefix is None else prefix
    store = store_of(subject, "ppm")
    if kept_fit_landmarks(store) is not None:
        return {f"{prefix}_fit_landmarks": str(fit_landmarks_path(store))}
    return {f"{prefix}_aligned": f"results/{subject}/align/aligned_pinna.ply",
            f"{prefix}_landmarks": str(Path(align_template(SimpleNamespace(subject=subject))).parent
                                       / "landmarks.yaml")}


def evaluation_report_inputs(wildcards) -> dict:
    """Everything the dataset evaluation reads: per subject the localisation, the target scan and, per
    condition, the distances, the collected HRTFs and the solve statuses (for the CPU time)."""
    inputs = {}
    for subject in SUBJECTS:
        inputs[f"{subject}_localisation"] = f"results/{subject}/localisation/qe_pe.json"
        inputs[f"{subject}_target"] = f"results/{subject}/target/pinna_target.ply"
        # the regions of the scan (where the geometry differs): the template's landmarks on the aligned PPM, those
        # of the fit that made the kept PPM head where the store keeps them (then no template or alignment needed)
        inputs.update(fit_landmark_inputs(subject))
        for condition in evaluation_conditions(subject):
            inputs[f"{subject}_{condition}_distances"] = f"results/{subject}/evaluation/{condition}/distances.json"
            inputs[f"{subject}_{condition}_hrtf"] = f"results/{subject}/hrtf/{condition}/HRTF.sofa"
            inputs[f"{subject}_{condition}_head"] = head_mesh_of(subject, condition)
            inputs[f"{subject}_{condition}_steps"] = steps_of(subject, condition)
    return inputs


def subject_report_inputs(wildcards):
    """Every per-subject result the report shows (the localisation only when HRTFs are computed)."""
    base = f"results/{wildcards.subject}"
    inputs = {"align": f"{base}/align/summary.json", "remesh": f"{base}/remesh/validation.json"}
    if config["hrtf"]["enabled"]:
        inputs["localisation"] = f"{base}/localisation/qe_pe.json"
    if DEMO:  # the demo's fidelity note and the parameters its ear was made with
        inputs["demo"] = str(DATA_ROOT / wildcards.subject / "demo.json")
        inputs["truth"] = str(DATA_ROOT / wildcards.subject / "truth_parameters.json")
    return inputs


def dataset_report_inputs(wildcards):
    """Every subject report (and, in the demo, one subject's fidelity note)."""
    inputs = {"subjects": expand("results/{subject}/report.html", subject=SUBJECTS)}
    if DEMO:
        inputs["demo"] = str(DATA_ROOT / SUBJECTS[0] / "demo.json")
    return inputs


def get_final_output():
    """Everything `snakemake --cores 2` makes: PPM pictures; per subject (demo or dataset) the alignment,
    the head with the PPM pinna stitched in and remeshed, and the report; with hrtf.enabled (always in
    the demo) the HRTFs of the reference and PPM heads and their localisation comparison; the dataset
    report."""
    out = [
        "results/ppm/default_ppm.png",
        "results/ppm/range_sheet.png",
        "results/ppm/default_ppm.blend",
        "results/ppm/default_parameters.csv",
    ]
    out += [f"results/{s}/align/summary.json" for s in SUBJECTS]
    out += [f"results/{s}/remesh/validation.json" for s in SUBJECTS]
    if config["hrtf"]["enabled"]:
        out += [f"results/{s}/localisation/qe_pe.json" for s in SUBJECTS]
    out += [f"results/{s}/report.html" for s in SUBJECTS] + ["results/dataset_report.html"]
    if EVALUATION_FOLDER and config["hrtf"]["enabled"]:
        out.append(f"{EVALUATION_FOLDER}/summary.csv")
    return out


def solve_plan_text() -> str | None:
    """The solve plan of this run (reporting/solve_plan.py): NumCalc's steps to solve and restore, or the embedded
    solver's heads with their predicted time on the configured backend; None when nothing is solved."""
    if not config["hrtf"]["enabled"]:
        return None
    if config["hrtf"]["solver"] == "embedded":
        from reporting.solve_plan import embedded_plan_text

        heads = [(subject, variant, head_mesh_of(subject, variant))
                 for subject in SUBJECTS for variant in solved_variants(subject)]
        return embedded_plan_text(heads, config["hrtf"].get("embedded_device", "auto"), len(hrtf_frequencies()))
    from reporting.solve_plan import plan_rows, plan_text

    heads = [(subject, variant) for subject in SUBJECTS for variant in solved_variants(subject)]
    projects = {(subject, variant): f"results/{subject}/hrtf/{variant}/project" for subject, variant in heads}
    rows = plan_rows(config["hrtf"]["step_store"] or None, heads, len(hrtf_frequencies()),
                     [int(s) for s in hrtf_sources()], projects)
    return plan_text(rows, workflow.cores or 1)
