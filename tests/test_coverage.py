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


def test_an_oracle_along_the_normals_keeps_the_scans_heights(ear):
    """The oracle of benchmarks/new_listener.py --blind-oracle: a holed scan 0.3 mm out along the crop's normals, and
    0.7 mm out on a plateau 4 mm round the scapha: each seen vertex of the crop lands on the scan along its normal
    (0.3 mm, 0.7 on the plateau), the cymba's core stays where the truth has it, and the surface is the crop's one
    connected mesh."""
    from reporting.stitched_region import heights_where_seen, seen_by

    crop, landmarks = ear
    bump_centre = crop.vertices[np.argmin(np.linalg.norm(crop.vertices - landmarks["scapha_mid"], axis=1))]
    bump = np.linalg.norm(crop.vertices - bump_centre, axis=1) < 4.0
    out = 0.3 + 0.4 * bump
    offset = trimesh.Trimesh(crop.vertices + out[:, None] * crop.vertex_normals, crop.faces, process=False)
    keep = np.linalg.norm(crop.vertices - landmarks["cymba_conchae"], axis=1) > 6.0
    holed = offset.submesh([np.flatnonzero(keep[crop.faces].all(axis=1))], append=True)
    oracle, placing = heights_where_seen(holed, crop)
    assert np.array_equal(oracle.faces, crop.faces)
    moved = np.linalg.norm(oracle.vertices - crop.vertices, axis=1)
    blind = ~seen_by(holed.vertices, crop.vertices)
    assert blind.sum() > 10 and np.all(moved[blind] == 0.0)
    assert placing["crossed"] > 0.97 * placing["seen_vertices"]
    inner = ~blind & keep & (np.linalg.norm(crop.vertices - bump_centre, axis=1) > 5.0)
    assert np.median(moved[inner]) == pytest.approx(0.3, abs=0.02)
    core = ~blind & (np.linalg.norm(crop.vertices - bump_centre, axis=1) < 2.0)
    assert core.sum() > 5 and np.median(moved[core]) == pytest.approx(0.7, abs=0.05)
