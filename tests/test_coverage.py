"""What a listener's ear scan saw (reporting/coverage.py): the share of each region of the fitted pinna with a scan
point nearby, the advice where a region was not seen, and the report's section."""
from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from conftest import ROOT


@pytest.fixture()
def ear(sonicom):
    """P143's clean crop as the fitted surface and the landmarks of its kept PPM fit (mm)."""
    crop = trimesh.load(sonicom / "P143" / "pinna_left_crop.ply", process=False, force="mesh")
    kept = json.loads((ROOT / "evaluation/sonicom/steps/P143/ppm/fit_landmarks.json").read_text())
    return crop, {name: np.asarray(position) for name, position in kept["landmarks_mm"].items()}


def test_a_hole_in_the_cymba_is_found_and_named(ear):
    """A scan with every point within 6 mm of the cymba conchae landmark cut away: the cymba is unseen, the rest of
    the pinna seen, and the advice names the left cymba conchae alone."""
    from reporting.coverage import coverage_advice, pinna_coverage

    crop, landmarks = ear
    holed = crop.vertices[np.linalg.norm(crop.vertices - landmarks["cymba_conchae"], axis=1) > 6.0]
    rows = {row["region"]: row for row in pinna_coverage(crop.vertices, crop.faces, holed, landmarks)}
    assert rows["cymba conchae"]["seen_share"] < 0.1
    assert rows["helix"]["seen_share"] == pytest.approx(1.0) and rows["cavum conchae"]["seen_share"] > 0.9
    assert 0.95 < rows["whole pinna"]["seen_share"] < 1.0
    advice = coverage_advice({"left": list(rows.values())})
    assert len(advice) == 1 and advice[0].startswith("rescan the left cymba conchae")
    whole = pinna_coverage(crop.vertices, crop.faces, crop.vertices, landmarks)
    assert coverage_advice({"left": whole, "right": whole})[0].startswith("every region of both ears was seen")


def test_the_listener_page_shows_what_each_scan_saw(ear, tmp_path):
    from reporting.coverage import coverage_picture, pinna_coverage
    from reporting.listener import _coverage_html

    crop, landmarks = ear
    half = crop.vertices[crop.vertices[:, 2] > 0.0]  # the upper half seen: the lobule is not
    coverage = {"left": pinna_coverage(crop.vertices, crop.faces, half, landmarks),
                "right": pinna_coverage(crop.vertices, crop.faces, crop.vertices, landmarks)}
    page = _coverage_html(coverage)
    assert "What the scans saw" in page and "rescan the left lobule" in page and "coverage_right.png" in page
    picture = coverage_picture(crop.vertices, crop.faces, half, tmp_path / "coverage_left.png", "left ear")
    assert picture.stat().st_size > 10_000


def test_a_scan_completed_where_it_was_blind_gets_the_hole_back(ear):
    """The oracle of benchmarks/new_listener.py --oracle: a scan 0.3 mm off the crop along its normals with the cymba
    cut out (6 mm round its landmark), completed by the clean crop: the crop's connected surface, its vertices the
    scan saw moved onto the scan (0.3 mm), those it never saw (the cymba's core) left where the truth has them, and
    then every region seen."""
    from reporting.coverage import pinna_coverage
    from reporting.stitched_region import completed_where_blind, seen_by

    crop, landmarks = ear
    offset = trimesh.Trimesh(crop.vertices + 0.3 * crop.vertex_normals, crop.faces, process=False)
    keep = np.linalg.norm(crop.vertices - landmarks["cymba_conchae"], axis=1) > 6.0
    holed = offset.submesh([np.flatnonzero(keep[crop.faces].all(axis=1))], append=True)
    completed = completed_where_blind(holed, crop)
    assert np.array_equal(completed.faces, crop.faces)
    moved = np.linalg.norm(completed.vertices - crop.vertices, axis=1)
    blind = ~seen_by(holed.vertices, crop.vertices)
    assert blind.sum() > 10 and np.all(moved[blind] == 0.0)
    assert np.median(moved[~blind]) == pytest.approx(0.3, abs=0.03)
    rows = {row["region"]: row for row in pinna_coverage(crop.vertices, crop.faces, completed.vertices, landmarks)}
    assert rows["cymba conchae"]["seen_share"] == pytest.approx(1.0)


def test_a_scan_with_its_blind_parts_added_keeps_what_it_saw(ear):
    """The blind-parts oracle of benchmarks/new_listener.py --blind-oracle: the same holed scan 0.3 mm off the crop
    keeps every one of its points where they were, and the crop's faces are added over the cymba's core only, so that
    the cymba is seen again and nothing the scan saw moves."""
    from reporting.coverage import pinna_coverage
    from reporting.stitched_region import seen_by, with_blind_parts

    crop, landmarks = ear
    offset = trimesh.Trimesh(crop.vertices + 0.3 * crop.vertex_normals, crop.faces, process=False)
    keep = np.linalg.norm(crop.vertices - landmarks["cymba_conchae"], axis=1) > 6.0
    holed = offset.submesh([np.flatnonzero(keep[crop.faces].all(axis=1))], append=True)
    oracle = with_blind_parts(holed, crop)
    assert np.array_equal(oracle.vertices[:len(holed.vertices)], holed.vertices)
    assert np.array_equal(oracle.faces[:len(holed.faces)], holed.faces)
    added = oracle.vertices[len(holed.vertices):]
    blind = ~seen_by(holed.vertices, crop.vertices)
    assert 10 < len(added) <= blind.sum()
    # the added points are the truth's own, all within the hole, none where the scan saw
    assert np.allclose(trimesh.proximity.closest_point(crop, added)[1], 0.0, atol=1e-9)
    assert np.all(np.linalg.norm(added - landmarks["cymba_conchae"], axis=1) < 6.0)
    rows = {row["region"]: row for row in pinna_coverage(crop.vertices, crop.faces, oracle.vertices, landmarks)}
    assert rows["cymba conchae"]["seen_share"] == pytest.approx(1.0)
