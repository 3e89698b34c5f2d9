"""pipeline.run_plan: what a run makes for which subject (the Python behind rules/common.smk), on the demo config
and on the paper's SONICOM config with the committed step store."""
from __future__ import annotations

import copy
import os
from pathlib import Path

import pytest
import yaml
from snakemake.utils import validate

from pipeline.run_plan import RunConfigError, RunPlan, apply_demo_overrides, configfile_settings

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = ROOT / "config" / "schema.yaml"


def _merged(base: dict, update: dict) -> dict:
    out = copy.deepcopy(base)
    for key, value in update.items():
        out[key] = _merged(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def _config(*files: str, **overrides) -> dict:
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    for name in files:
        config = _merged(config, yaml.safe_load((ROOT / name).read_text()))
    config = _merged(config, overrides)
    validate(config, str(SCHEMA))
    if not config["data_root"]:
        apply_demo_overrides(config)
        validate(config, str(SCHEMA))
    return config


@pytest.fixture()
def in_root(monkeypatch):
    monkeypatch.chdir(ROOT)  # the plan's paths are relative to the project root, as in the workflow


def test_the_demo_plan(in_root):
    config = _config()
    run = RunPlan(config)
    assert run.demo and run.subjects == ["demo01", "demo02"]
    assert run.demo_seed("demo02") == config["demo"]["seed"] + 1
    assert run.align_template("demo01").endswith("template_left.ply")
    assert config["hrtf"]["solver"] == "embedded"  # the demo's hrtf keys replaced the general ones
    assert run.steps_of("demo01", "ppm") == ["results/demo01/hrtf/embedded.json"]
    assert run.solved_variants("demo01") == ["reference", "ppm"]
    final = run.final_output()
    assert "results/demo02/report.html" in final and "results/dataset_report.html" in final
    assert run.subject_report_inputs("demo01")["truth"] == "results/demo_data/demo01/truth_parameters.json"
    assert run.embedded_mem_mb(["results/no_such/project"]) == 4096  # before the export: the dry-run default
    def no_cores():  # a cluster run without --cores: Snakemake's workflow.cores raises
        raise RuntimeError("no --cores")

    assert "embedded" in run.solve_plan_text(no_cores)  # the embedded plan never asks for the cores


def test_the_paper_plan_reads_the_committed_step_store(in_root, sonicom):
    run = RunPlan(_config("config/paper_sonicom.yaml"))
    assert run.subjects == ["P039", "P067", "P143"]
    assert run.evaluation_conditions("P143") == ["original", "ppm", "own_pinna", "default_ppm", "ppm_detail",
                                                 "ppm_hard", "ppm_detail_hard", "nricp_hard", "scan_hard"]
    assert run.evaluation_conditions("P067") == ["original", "ppm", "own_pinna", "default_ppm", "ppm_detail",
                                                 "ppm_hard", "ppm_detail_hard", "scan_hard"]
    # the defective scan made watertight is cut under the rim of the PPM fitted to it
    assert run.control_pinna("P067", "scan_hard") == "results/P067/controls/scan_hard/pinna.ply"
    # the personal-detail layer is judged on the fit's segmented target but drawn towards the whole scan
    assert run.detail_target("P067", "ppm_detail_hard") == "results/P067/controls/hard/target/pinna_target.ply"
    assert run.detail_evidence("P067", "ppm_detail_hard") == "results/P067/controls/hard/scan.ply"
    assert run.detail_evidence("P067", "ppm_detail").endswith("sonicom/P067/pinna_left_crop.ply")
    assert list(run.not_solved("P067")) == ["nricp_hard"] and "2 holes" in run.not_solved("P067")["nricp_hard"]
    assert run.not_solved("P143") == {}
    assert run.evaluation_conditions("P039") == ["original", "ppm", "own_pinna", "default_ppm", "ppm_detail"]
    # default_ppm is banded, except P143's, solved on its full mesh before (hrtf.frequency_bands.full_mesh_heads)
    assert run.banded("default_ppm", "P067") and not run.banded("default_ppm", "P143")
    assert run.step_project("P143", "default_ppm", 1) == "results/P143/hrtf/default_ppm/project"
    assert run.step_project("P067", "default_ppm", 1) == "results/P067/hrtf/default_ppm/band_1/project"
    assert run.head_mesh_of("P143", "ppm_detail") == "evaluation/sonicom/steps/P143/ppm_detail/head.ply"
    # the PPM head is the one kept beside its solved steps, not a rebuild
    assert run.head_mesh_of("P143", "ppm") == "evaluation/sonicom/steps/P143/ppm/head.ply"
    assert run.head_mesh_of("P143", "original").endswith("sonicom/P143/head_graded_left.ply")
    # the heads from the defective scan are solved on a mesh per frequency band, each band's kept with its steps
    assert run.step_store("P143", "ppm_detail_hard", 1) == "evaluation/sonicom/steps/P143/ppm_detail_hard/band_1"
    assert run.step_project("P143", "nricp_hard", 40) == "results/P143/hrtf/nricp_hard/project"
    steps = run.steps_of("P067", "ppm")
    assert len(steps) == 40 and steps[0] == "results/P067/hrtf/ppm/steps/source_1/steps_1-1.json"
    # the dataset's own reference HRIRs are not a solved variant
    assert run.solved_variants("P039") == ["original", "ppm", "own_pinna", "default_ppm", "ppm_detail"]
    assert run.reference_sofa("P039") == "../shared/data/sonicom/P039/hrir_mesh2hrtf_48k.sofa"
    assert len(run.reference_frequencies("P039")) == 40
    inputs = run.evaluation_report_inputs()
    assert inputs["P143_default_ppm_hrtf"] == "results/P143/hrtf/default_ppm/HRTF.sofa"
    assert inputs["P143_hard_scan"] == "results/P143/controls/hard/scan.ply"
    assert inputs["nonindividual_ku100"] == "../shared/data/hrtf/measured_ku100_bernschuetz.npz"
    assert "evaluation/sonicom/summary.csv" in run.final_output()
    assert "steps" in run.solve_plan_text(lambda: 2)  # NumCalc's plan counts the steps on the cores asked for
    # before the export no NumCalc prediction: config hrtf.step_runtime_min per step
    project = "results/no_such/project"
    assert run.numcalc_step_runtime_min(project, 1, 3, 1) == 3 * run.hrtf["step_runtime_min"]
    assert run.numcalc_step_mem_mb(project, 1, 1, 2) == int(1024 * 2.0 * 1.2 * 1.5)


def test_steps_per_job_groups_the_steps(in_root, sonicom):
    run = RunPlan(_config("config/paper_sonicom.yaml", hrtf={"steps_per_job": 16}))
    assert [Path(s).name for s in run.steps_of("P143", "ppm")] == ["steps_1-16.json", "steps_17-32.json",
                                                                    "steps_33-40.json"]


def test_bad_data_roots_are_named(in_root, tmp_path, sonicom):
    with pytest.raises(RunConfigError, match="no such folder"):
        RunPlan(_config(data_root=str(tmp_path / "missing")))
    with pytest.raises(RunConfigError, match="no <subject>/pinna_left_crop.ply under it"):
        RunPlan(_config(data_root=str(tmp_path)))
    table = tmp_path / "subjects.csv"
    table.write_text("subject\nP143\nP999\n")
    with pytest.raises(RunConfigError, match="P999 have no pinna_left_crop.ply"):
        RunPlan(_config(data_root=str(sonicom), subjects_table=str(table)))
    with pytest.raises(RunConfigError, match="unknown HRTF variant"):
        RunPlan(_config(data_root=str(sonicom))).head_mesh_of("P143", "nricp")


def test_configfile_settings_spell_out_files_outside_the_checkout(tmp_path):
    outside = tmp_path / "extra.yaml"
    outside.write_text("hrtf:\n  steps_per_job: 4\n")
    inside, settings = configfile_settings([str(ROOT / "config/paper_sonicom.yaml"), str(outside)], ROOT)
    assert inside == [os.path.join("config", "paper_sonicom.yaml")]
    assert settings == [f"{outside}: hrtf.steps_per_job = 4"]


def test_a_banded_head_solves_each_band_in_its_own_project(in_root, sonicom):
    bands = {"variants": ["ppm"], "bands": [{"up_to_hz": 3000.0, "edges_mm": [3.0, 5.0, 8.0, 12.0]},
                                            {"up_to_hz": 6000.0, "edges_mm": [2.0, 3.0, 5.0, 8.0]}]}
    run = RunPlan(_config("config/paper_sonicom.yaml", hrtf={"frequency_bands": bands, "steps_per_job": 4}))
    assert run.banded("ppm") and not run.banded("original")
    assert [len(steps) for steps in run.band_steps()] == [11, 7] and run.full_mesh_steps()[0] == 19
    # jobs never straddle a band's edge: 4 steps each within a band
    names = [Path(s).name for s in run.steps_of("P143", "ppm") if "source_1" in s]
    assert names == ["steps_1-4.json", "steps_5-8.json", "steps_9-11.json", "steps_12-15.json", "steps_16-18.json",
                     "steps_19-22.json", "steps_23-26.json", "steps_27-30.json", "steps_31-34.json",
                     "steps_35-38.json", "steps_39-40.json"]
    assert run.step_project("P143", "ppm", 12) == "results/P143/hrtf/ppm/band_2/project"
    assert run.step_project("P143", "ppm", 19) == "results/P143/hrtf/ppm/project"
    assert run.step_project("P143", "original", 1) == "results/P143/hrtf/original/project"
    assert run.step_store("P143", "ppm", 1) == "evaluation/sonicom/steps/P143/ppm/band_1"
    assert run.band_projects("P143", "ppm") == {"results/P143/hrtf/ppm/band_1/project": list(range(1, 12)),
                                                "results/P143/hrtf/ppm/band_2/project": list(range(12, 19))}
    assert run.band_remesh_bands(2)[0] == {"up_to_mm": 12.0, "edge_mm": 2.0, "max_deviation_mm": 0.2}
    assert run.band_export_inputs("P143", "ppm", 1)["sources"] == "results/P143/hrtf/ppm/band_1/sources.json"
    # the solve plan has a row per band mesh, each with its own steps; the full mesh's steps 19-40 of the committed
    # PPM head are in the store for this very head (the band meshes' are not yet)
    plan = run.solve_plan_text(lambda: 2)
    exported = Path("results/P143/hrtf/ppm/project/NumCalc").is_dir()  # a clone has not exported it yet
    stored = "22 stored for this head" if exported else "22 stored, not yet checked against the rebuilt head"
    assert f"P143 ppm: 0 of 22 steps to solve ({stored})" in plan
    assert "P143 ppm/band_1: 11 of 11 steps to solve (0 stored)" in plan and "P143 ppm/band_2: 7 of 7" in plan
    bad = {**bands, "bands": [{"up_to_hz": 3000.0, "edges_mm": [3.0, 5.0]}]}
    with pytest.raises(RunConfigError, match="2 edge lengths for the 4 distance bands"):
        RunPlan(_config("config/paper_sonicom.yaml", hrtf={"frequency_bands": bad}))


def test_a_listener_is_solved_as_its_own_subject_on_the_full_grid(in_root, tmp_path, sonicom):
    """A run with listeners makes only theirs: each listener's remeshed head is the 'personal' variant of the
    subject listeners/<name>, solved with both ears on the full grid, compared in its report with the other
    listeners and the comparison sets; names and files are checked before anything runs."""
    scan = tmp_path / "head.stl"
    scan.write_bytes(b"solid x\nendsolid x\n")
    other = sonicom / "P039" / "hrir_mesh2hrtf_48k.sofa"
    ku100 = sonicom.parent / "hrtf" / "measured_ku100_bernschuetz.npz"
    measured = {"name": "ku100", "file": str(ku100), "kind": "dummy head", "sampling_rate_hz": 48000}
    config = _config(listeners=[{"name": "anna", "head": str(scan)}, {"name": "ben", "head": str(scan)}],
                     listener={"template": "", "comparison_sets": [str(other), measured]})
    run = RunPlan(config)
    assert run.listener_subjects == ["listeners/anna", "listeners/ben"]
    assert run.final_output()[-1] == "results/listeners/ben/report.html"
    assert not any(path.startswith("results/ppm/") for path in run.final_output())
    assert run.solved_variants("listeners/anna") == ["personal"]
    assert run.head_mesh_of("listeners/anna", "personal") == "results/listeners/anna/remesh/head.ply"
    assert run.export_settings("listeners/anna")["grid"] == "full"
    assert run.grid_inputs("listeners/anna") == {}
    # listener.dataset_grid: the dataset's directions join the listener's full grid
    with_dataset = RunPlan(_config(listeners=[{"name": "anna", "head": str(scan)}],
                                   listener={"dataset_grid": str(other), "comparison_sets": []}))
    assert with_dataset.grid_inputs("listeners/anna") == {"grid_sofa": str(other)}
    assert run.listener_comparisons("anna") == {"ben": "results/listeners/ben/hrtf/personal/HRTF.sofa",
                                                "P039": str(other), "ku100": str(ku100)}
    # a measured set keeps its kind and rate for the report's table
    assert run.listener_comparison_sets("anna")["ku100"] == {"file": str(ku100), "kind": "dummy head",
                                                             "sampling_rate_hz": 48000}
    assert run.listener_template().endswith("template_left.ply")
    # the personal-detail layer is on by default; listener.personal_detail: false stitches the fits as they are
    assert run.listener_personal_detail
    assert run.listener_pinna("anna", "right") == "results/listeners/anna/detail/right/aligned_pinna.ply"
    bare = RunPlan(_config(listeners=[{"name": "anna", "head": str(scan)}],
                           listener={"personal_detail": False, "comparison_sets": []}))
    assert bare.listener_pinna("anna", "right") == "results/listeners/anna/align/right/aligned_pinna.ply"
    assert not bare.listener_personal_detail
    # listener.personal_detail_settings: the layer laid with settings other than the packaged ones, names checked
    assert run.listener_detail_settings == {}
    floored = RunPlan(_config(listeners=[{"name": "anna", "head": str(scan)}],
                              listener={"personal_detail_settings": {"noise_stiffness_factor": 1.0},
                                        "comparison_sets": []}))
    assert floored.listener_detail_settings == {"noise_stiffness_factor": 1.0}
    misspelt = RunPlan(_config(listeners=[{"name": "anna", "head": str(scan)}],
                               listener={"personal_detail_settings": {"noise_stiffnes": 1.0}, "comparison_sets": []}))
    with pytest.raises(RunConfigError, match="personal_detail_settings.*noise_stiffnes"):
        misspelt.listener_detail_settings
    # listener.scanned_head (a validation run): the head as scanned, remeshed as the personal head, solved beside it
    assert "results/listeners/anna/hrtf/scanned/HRIR.sofa" not in run.final_output()
    validating = RunPlan(_config(listeners=[{"name": "anna", "head": str(scan)}],
                                 listener={"scanned_head": True, "comparison_sets": []}))
    assert validating.solved_variants("listeners/anna") == ["personal", "scanned"]
    assert validating.head_mesh_of("listeners/anna", "scanned") == "results/listeners/anna/scanned/head.ply"
    assert "results/listeners/anna/hrtf/scanned/HRIR.sofa" in validating.final_output()
    assert validating.export_settings("listeners/anna")["grid"] == "full"
    with pytest.raises(RunConfigError, match="given twice"):
        RunPlan(_config(listeners=[{"name": "anna", "head": str(scan)}] * 2))
    # separate ear scans are registered onto the head's ears unless they share the head scan's coordinates
    assert run.listener_ear_scan_frame("anna") == "any"
    placed = RunPlan(_config(listeners=[{"name": "anna", "head": str(scan), "ear_scan_frame": "head"}]))
    assert placed.listener_ear_scan_frame("anna") == "head"
    with pytest.raises(RunConfigError, match="ear_scan_frame"):
        RunPlan(_config(listeners=[{"name": "anna", "head": str(scan), "ear_scan_frame": "scanner"}]))
    with pytest.raises(RunConfigError, match="missing or empty"):
        RunPlan(_config(listeners=[{"name": "anna", "head": str(tmp_path / "none.ply")}]))
    with pytest.raises(RunConfigError, match="listener.template"):
        RunPlan(_config(listeners=[{"name": "anna", "head": str(scan)}],
                        listener={"template": str(tmp_path), "comparison_sets": []})).listener_template()
