# Config validation, wildcard constraints and the input functions of the rules (no rules here). What a run makes
# for which subject lives in pipeline/run_plan.py (tested in tests/test_run_plan.py); this file passes the
# wildcards on.
from pathlib import Path

from snakemake.utils import validate

from reporting.solve_plan import BUILT_HEADS  # ppm and the controls: heads kept in the step store beside their steps
from pipeline.run_plan import (CONTROLS, HRTF_VARIANTS, RunPlan, apply_demo_overrides, check_embedded_backend,
                               configfile_settings)

validate(config, "../config/schema.yaml")
if not config["data_root"] and not config.get("listeners"):  # a listener run keeps the real bands
    apply_demo_overrides(config)  # the demo's hrtf keys and remeshing bands (checked again)
    validate(config, "../config/schema.yaml")
if config.get("listeners"):
    config["hrtf"]["enabled"] = True  # a new listener's run always ends in its HRTFs (hrtf.enabled is the dataset's)

RUN = RunPlan(config)
DEMO = RUN.demo
DATA_ROOT = RUN.data_root
SUBJECTS = RUN.subjects
EVALUATION_FOLDER = RUN.evaluation_folder
#: How the evaluation was configured, for its README (configfiles inside the working directory, and the settings
#: of those outside it, which a clone does not have).
EVALUATION_CONFIGFILES, EVALUATION_OUTSIDE_SETTINGS = configfile_settings(workflow.overwrite_configfiles, Path.cwd())

check_embedded_backend(config)


wildcard_constraints:
    subject="|".join(SUBJECTS + RUN.listener_subjects),
    variant="|".join(HRTF_VARIANTS),
    control="|".join(CONTROLS),
    source="[12]",
    listener="|".join(RUN.listeners) or "no-listener",
    side="left|right",
    band="[0-9]+",
    first="[0-9]+",
    last="[0-9]+",


# plain functions of the run
evaluation_conditions = RUN.evaluation_conditions
head_mesh_of = RUN.head_mesh_of
store_of = RUN.store_of
solved_variants = RUN.solved_variants


def template_params():
    """Settings of the template build, from config/template."""
    return config["template"]


def evaluation_report_inputs(wildcards):
    return RUN.evaluation_report_inputs()


def dataset_report_inputs(wildcards):
    return RUN.dataset_report_inputs()


def get_final_output():
    return RUN.final_output()


def solve_plan_text():
    # the cores are read only where the NumCalc plan needs them: a cluster run (--profile, no --cores) has none
    return RUN.solve_plan_text(lambda: workflow.cores or 1)


# input, param and resource functions: the wildcards passed on
def demo_seed(wildcards):
    return RUN.demo_seed(wildcards.subject)


def align_template(wildcards):
    return RUN.align_template(wildcards.subject)


def detail_target(wildcards):
    return RUN.detail_target(wildcards.subject, wildcards.detailed)


def detail_evidence(wildcards):
    return RUN.detail_evidence(wildcards.subject, wildcards.detailed)


def control_pinna(wildcards):
    return RUN.control_pinna(wildcards.subject, wildcards.control)


def hrtf_export_inputs(wildcards):
    return RUN.hrtf_export_inputs(wildcards.subject, wildcards.variant)


def step_store(wildcards):
    return RUN.store_of(wildcards.subject, wildcards.variant)


def solved_steps(wildcards):
    return RUN.steps_of(wildcards.subject, wildcards.variant)


def numcalc_step_project(wildcards):
    return RUN.step_project(wildcards.subject, wildcards.variant, int(wildcards.first))


def numcalc_step_store(wildcards):
    return RUN.step_store(wildcards.subject, wildcards.variant, int(wildcards.first))


def band_projects(wildcards):
    return list(RUN.band_projects(wildcards.subject, wildcards.variant))


def band_head_inputs(wildcards):
    return RUN.band_head_inputs(wildcards.subject, wildcards.variant)


def band_export_inputs(wildcards):
    return RUN.band_export_inputs(wildcards.subject, wildcards.variant, int(wildcards.band))


def reference_frequencies(wildcards):
    return RUN.reference_frequencies(wildcards.subject)


def localisation_inputs(wildcards):
    return RUN.localisation_inputs(wildcards.subject)


def subject_report_inputs(wildcards):
    return RUN.subject_report_inputs(wildcards.subject)


def numcalc_step_mem_mb(wildcards, input, attempt):
    return RUN.numcalc_step_mem_mb(input.project, int(wildcards.first), int(wildcards.last), attempt)


def numcalc_step_runtime_min(wildcards, input, attempt):
    return RUN.numcalc_step_runtime_min(input.project, int(wildcards.first), int(wildcards.last), attempt)


def embedded_gpus(wildcards):
    return 1 if RUN.embedded_on_gpu() else 0


def embedded_runtime_min(wildcards, input, attempt):
    return RUN.embedded_runtime_min(input.projects, attempt)


def embedded_mem_mb(wildcards, input):
    return RUN.embedded_mem_mb(input.projects)


def _measured(rule, key):
    """Resource function: request ``key`` (mem_mb, runtime in minutes) of a rule from its measured peak
    (workflow/resources.yaml, reporting/resources.py), +50 % per retry."""
    from reporting.resources import requests

    base = requests(rule)[key]
    return lambda wildcards, attempt: int(base * (1 + 0.5 * (attempt - 1)))


def measured_mem_mb(rule):
    return _measured(rule, "mem_mb")


def measured_runtime(rule):
    return _measured(rule, "runtime")
