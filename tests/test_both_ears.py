"""stitching.both_ears: two different PPM pinnae stitched into one head, the right one fitted as a left ear and
mirrored back; the head stays one closed surface with both ear canals, and each pinna sits where it was put."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from demo.head import head_with_pinnae
from mesh2hrtf_io.ear_canal import ear_canal_elements
from ppm.parameters import random_parameters
from stitching.both_ears import mirror_left_right, stitch_both_ears
from stitching.remesh import self_intersections


@pytest.mark.slow
def test_two_different_pinnae_go_into_one_head(model):
    rng = np.random.default_rng(42)
    left = model.mesh(random_parameters(rng, 0.4))
    right_as_left = model.mesh(random_parameters(rng, 0.4))
    head = head_with_pinnae(left)  # the demo head: the first pinna on both sides
    both = stitch_both_ears(head, left, right_as_left)
    assert both.is_watertight and both.is_winding_consistent and both.volume > 0
    assert self_intersections(both) == 0
    for side in ("left", "right"):
        assert len(ear_canal_elements(both, side)) > 0
    # every vertex of each pinna is on the result, the right one mirrored to the right ear
    for pinna in (left, mirror_left_right(right_as_left)):
        distance = trimesh.proximity.closest_point(both, np.asarray(pinna.vertices)[::10])[1]
        assert np.median(distance) < 1e-6
    # and the two sides differ as the two pinnae do
    gap = trimesh.proximity.closest_point(both, np.asarray(mirror_left_right(left).vertices)[::10])[1]
    assert np.median(gap) > 0.05
