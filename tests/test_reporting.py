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
from ppm.parameters import PinnaParameters
from reporting import write_dataset_report, write_subject_report
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
