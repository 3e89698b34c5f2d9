"""Subject and dataset reports from real stage outputs (alignment of P143's scan, its head stitched and
remeshed, a localisation comparison on measured HRTFs)."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import trimesh

from amt_bridge.evaluation import compare_conditions, comparison_summary
from amt_bridge.plots import save_error_bars, save_prediction_matrices
from ppm.align import align, prepare_target
from ppm.align.report import write_alignment
from ppm.parameters import PinnaParameters, parameter_specs
from reporting import write_dataset_report, write_subject_report
from reporting.cost import read_benchmark, solve_costs, subject_timings
from reporting.subject import parameter_recovery
from reporting.subject import read_distances
from stitching.pipeline import remesh_files, stitch_files


@pytest.fixture(scope="module")
def results(tmp_path_factory, model, sonicom):
    """results/P143/{align,stitch,remesh,localisation} made by the real stages."""
    root = tmp_path_factory.mktemp("results")
    base = root / "P143"
    target = prepare_target(sonicom / "P143" / "pinna_left_crop.ply", side="left", margin_mm=3.0)
    fit = align(model, target)
    model.set_parameters(fit.parameters)
    write_alignment(base / "align", model, target, fit)
    model.set_parameters(PinnaParameters.default())
    stitch_files(sonicom / "P143" / "head_graded_left.ply", base / "align" / "aligned_pinna.ply",
                 base / "stitch" / "stitched_head.ply", base / "stitch" / "stitch.json")
    remesh_files(base / "stitch" / "stitched_head.ply", base / "align" / "aligned_pinna.ply",
                 base / "remesh" / "head.ply", base / "remesh" / "validation.json")
    hrtf = sonicom.parent / "hrtf"
    s, predictions = compare_conditions(hrtf / "measured_axd_example1.sofa", {"ppm": hrtf / "measured_axd_example2.sofa"})
    (base / "localisation").mkdir()
    (base / "localisation" / "qe_pe.json").write_text(json.dumps(comparison_summary("ref", 8.0, s, predictions)))
    save_error_bars(predictions, base / "localisation" / "qe_pe_bars.png")
    save_prediction_matrices(predictions["ppm"], base / "localisation" / "ppm_matrix.png")
    return root


def test_distances_read_back_from_the_ply(results):
    distances = read_distances(results / "P143" / "align" / "distances.ply")
    summary = json.loads((results / "P143" / "align" / "summary.json").read_text())["distance_target_to_ppm"]
    assert np.median(distances) == pytest.approx(summary["median_mm"], abs=1e-3)


def test_subject_report_embeds_every_stage(results, tmp_path):
    page = write_subject_report("P143", results / "P143", tmp_path / "report.html", tmp_path / "figures").read_text()
    assert page.count("data:image/png;base64,") == 4  # deviations, histogram, QE/PE bars, PPM matrix
    for heading in ("Alignment of the PPM", "seam and BEM mesh", "baumgartner2014"):
        assert heading in page
    assert "reference_matrix.png: not made" in page  # a missing figure is named, not dropped silently
    assert (tmp_path / "figures" / "parameter_deviations.png").read_bytes()[:4] == b"\x89PNG"


def test_dataset_report_and_summary_csv(results, tmp_path):
    write_subject_report("P143", results / "P143", results / "P143" / "report.html", results / "P143" / "figures")
    write_dataset_report(results, ["P143"], tmp_path / "dataset.html", tmp_path / "summary.csv", tmp_path / "figs")
    rows = list(csv.DictReader((tmp_path / "summary.csv").open()))
    assert rows[0]["subject"] == "P143" and rows[0]["remesh_ok"] == "True"
    assert 0 < float(rows[0]["align_median_mm"]) < 1.0
    assert float(rows[0]["qe_reference_percent"]) == pytest.approx(8.0, abs=0.01)
    assert "P143/report.html" in (tmp_path / "dataset.html").read_text()


def test_parameter_recovery_groups_the_errors():
    specs = parameter_specs()
    location = next(s for s in specs if s.kind == "location")
    rotation = next(s for s in specs if s.kind == "rotation")
    truth = PinnaParameters.default()
    fitted = truth.with_values({location.name: location.default + 0.5, rotation.name: rotation.default - 2.0})
    rows = {r["group"].split()[0]: r for r in parameter_recovery(fitted, truth)}
    assert rows["location"]["max"] == pytest.approx(0.5) and rows["location"]["worst"] == location.name
    assert rows["location"]["median"] == 0.0
    assert rows["rotation"]["max"] == pytest.approx(2.0) and rows["shape"]["max"] == 0.0


def _benchmark(path, seconds: float, rss_mb: float) -> None:
    """A benchmark file as Snakemake writes it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"
                    f"{seconds}\t0:00:{int(seconds):02d}\t{rss_mb}\t1\t1\t1\t0\t0\t90.0\t{seconds}\n")


def test_stage_timings_of_one_subject_only(tmp_path):
    _benchmark(tmp_path / "align" / "align_ppm" / "S1.tsv", 4.5, 600.0)
    _benchmark(tmp_path / "align" / "align_ppm" / "S10.tsv", 9.0, 600.0)
    _benchmark(tmp_path / "hrtf" / "solve_embedded" / "S1_ppm.tsv", 30.0, 900.0)
    timings = subject_timings(tmp_path, "S1")
    assert [(t.rule, t.job, t.seconds) for t in timings] == [("align_ppm", "S1", 4.5), ("solve_embedded", "S1_ppm", 30.0)]
    (tmp_path / "empty.tsv").write_text("")
    with pytest.raises(ValueError, match="empty.tsv"):
        read_benchmark(tmp_path / "empty.tsv")


def test_demo_report_shows_the_note_the_recovery_and_the_cost(results, tmp_path):
    truth = tmp_path / "truth.json"
    fitted = PinnaParameters.read(results / "P143" / "align" / "parameters.json", out_of_range="clip")
    fitted.with_values({"Location_Size-Bendy_X": fitted.to_dict()["Location_Size-Bendy_X"] + 0.25},
                       out_of_range="clip").write(truth)
    _benchmark(tmp_path / "timings" / "align" / "align_ppm" / "P143.tsv", 4.5, 600.0)
    page = write_subject_report("P143", results / "P143", tmp_path / "report.html", tmp_path / "figures",
                                note="Demo fidelity: a test", truth=truth, timings_root=tmp_path / "timings").read_text()
    assert "Demo fidelity: a test" in page and "Recovery of the true parameters" in page
    assert "max 0.250 (Location_Size-Bendy_X)" in page
    assert "align_ppm (P143)" in page and "4.5 s, peak 600 MB" in page
    assert (tmp_path / "figures" / "parameter_recovery.png").is_file()


def test_dataset_report_lists_parameter_ranges_and_localisation(results, tmp_path):
    write_subject_report("P143", results / "P143", results / "P143" / "report.html", results / "P143" / "figures")
    write_dataset_report(results, ["P143"], tmp_path / "dataset.html", tmp_path / "summary.csv", tmp_path / "figs",
                         out_parameters_csv=tmp_path / "parameters.csv", note="Demo fidelity: a test")
    ranges = list(csv.DictReader((tmp_path / "parameters.csv").open()))
    assert len(ranges) == 144 and all(r["min"] == r["median"] == r["max"] for r in ranges)  # one subject
    page = (tmp_path / "dataset.html").read_text()
    assert "Demo fidelity: a test" in page and "Predicted localisation" in page
    assert (tmp_path / "figs" / "localisation_bars.png").read_bytes()[:4] == b"\x89PNG"


def test_solve_cost_of_a_subject_with_underscores_in_its_name(tmp_path):
    """NumCalc step jobs are matched by '<subject>_<variant>', not by splitting the name on underscores; the
    embedded solver's per-subject status gives each head's seconds, the job's first frequency (numba's
    compilation) left out of the per-frequency figure."""
    results = tmp_path / "results" / "P_01"
    for variant in ("reference", "ppm"):
        project = results / "hrtf" / variant / "project"
        (project / "ObjectMeshes" / "Reference").mkdir(parents=True)
        (project / "ObjectMeshes" / "Reference" / "Elements.txt").write_text("2000\n")
        (project / "parameters.json").write_text(json.dumps({"frequencies": [1000.0, 2000.0]}))
    _benchmark(tmp_path / "timings" / "hrtf" / "solve_numcalc_step" / "P_01_ppm_1_1-1.tsv", 30.0, 900.0)
    _benchmark(tmp_path / "timings" / "hrtf" / "solve_numcalc_step" / "P_01_ppm_1_2-2.tsv", 10.0, 900.0)
    _benchmark(tmp_path / "timings" / "hrtf" / "solve_numcalc_step" / "P_01_reference_1_1-2.tsv", 20.0, 800.0)
    costs = {c["variant"]: c for c in solve_costs(results, subject_timings(tmp_path / "timings", "P_01"))}
    assert costs["ppm"]["solve_seconds"] == 40.0 and costs["ppm"]["seconds_per_frequency"] == 20.0
    assert costs["reference"]["solve_seconds"] == 20.0 and costs["reference"]["elements"] == 2000
    assert costs["ppm"]["solver"] == "NumCalc"
    (results / "hrtf" / "embedded.json").write_text(json.dumps({"projects": {
        "reference": {"seconds_per_frequency": [80.0, 4.0]}, "ppm": {"seconds_per_frequency": [5.0, 3.0]}}}))
    costs = {c["variant"]: c for c in solve_costs(results, subject_timings(tmp_path / "timings", "P_01"))}
    assert costs["reference"]["solver"] == "embedded" and costs["reference"]["solve_seconds"] == 84.0
    assert costs["reference"]["seconds_per_frequency"] == 4.0 and costs["ppm"]["seconds_per_frequency"] == 4.0


def test_rule_requests_come_from_measured_peaks(tmp_path):
    """workflow/resources.yaml: the largest peak of each rule's benchmark files; requests 1.5 x memory + 512 MB
    and 3 x the time (floors 768 MB, 10 min); a peak only grows when remeasured; NumCalc steps are left to the
    cost model; the packaged file covers every rule the workflow submits."""
    import yaml

    from reporting.resources import DEFAULT_FILE, requests, rule_peaks, write_peaks

    timings = tmp_path / "timings"
    _benchmark(timings / "align" / "align_ppm" / "S1.tsv", 40.0, 900.0)
    _benchmark(timings / "align" / "align_ppm" / "S2.tsv", 400.0, 700.0)
    _benchmark(timings / "ppm" / "render_ppm" / "all.tsv", 5.0, 100.0)
    _benchmark(timings / "hrtf" / "solve_numcalc_step" / "S1_ppm_1_1-1.tsv", 200.0, 4000.0)
    peaks = rule_peaks([timings])
    assert peaks["align_ppm"] == {"max_rss_mb": 900.0, "seconds": 400.0, "jobs": 2}
    assert "render_ppm" in peaks and "solve_numcalc_step" not in peaks
    path = tmp_path / "resources.yaml"
    write_peaks(path, peaks, [str(timings)])
    assert requests("align_ppm", path) == {"mem_mb": 1862, "runtime": 20}
    assert requests("render_ppm", path) == {"mem_mb": 768, "runtime": 10}
    assert requests("never_measured", path) == {"mem_mb": 4000, "runtime": 60}
    write_peaks(path, {"align_ppm": {"max_rss_mb": 500.0, "seconds": 10.0, "jobs": 1}}, ["elsewhere"])
    assert yaml.safe_load(path.read_text())["rules"]["align_ppm"] == {"max_rss_mb": 900.0, "seconds": 400.0}
    packaged = yaml.safe_load(DEFAULT_FILE.read_text())["rules"]
    for rule in ("render_ppm", "make_demo_subject", "build_template", "prepare_target", "align_ppm", "stitch", "remesh",
                 "export_project", "solve_embedded", "collect_sofa", "localisation", "report_subject", "report_dataset"):
        assert packaged[rule]["max_rss_mb"] > 0 and packaged[rule]["seconds"] > 0, rule
