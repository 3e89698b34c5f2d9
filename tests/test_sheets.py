"""ppm.align.sheets: the facing sheets of a surface folded over itself and the barrier that keeps them apart while
fitting (a strip folded like the helix over the scapha, mm)."""
import numpy as np
import pytest

from core.self_intersections import self_intersecting_faces
from ppm.align.sheets import facing_sheets, sheet_terms

GAP_MM = 3.0


def folded_strip(length_mm: float = 12.0, width_mm: float = 4.0, step_mm: float = 0.5
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A strip along x at z = 0, bent round a half circle at x = length, and back along x at z = GAP_MM: vertices,
    faces (one consistent winding) and, per vertex, whether it lies on the upper sheet."""
    radius = GAP_MM / 2
    bend = np.pi * radius
    s = np.arange(0.0, 2 * length_mm + bend + 1e-9, step_mm)     # arc length along the strip
    along = np.where(s <= length_mm, s, np.where(s >= length_mm + bend, 2 * length_mm + bend - s, length_mm))
    angle = np.clip((s - length_mm) / radius, 0.0, np.pi)
    x = np.where((s > length_mm) & (s < length_mm + bend), length_mm + radius * np.sin(angle), along)
    z = radius - radius * np.cos(angle)
    y = np.arange(0.0, width_mm + 1e-9, step_mm)
    rows, columns = len(s), len(y)
    vertices = np.array([[x[r], y[c], z[r]] for r in range(rows) for c in range(columns)])
    faces = []
    for r in range(rows - 1):
        for c in range(columns - 1):
            a, b, d, e = r * columns + c, r * columns + c + 1, (r + 1) * columns + c, (r + 1) * columns + c + 1
            faces += [[a, d, b], [b, d, e]]
    return vertices, np.array(faces), vertices[:, 2] > radius


def lowered(vertices: np.ndarray, upper: np.ndarray, height_mm: float) -> np.ndarray:
    """The strip with its upper sheet's far end (x <= 6 mm) lowered to ``height_mm``, ramping back to the fold's
    height over x = 6 to 9 mm (the bend untouched)."""
    moved = vertices.copy()
    ramp = np.clip((9.0 - vertices[:, 0]) / 3.0, 0.0, 1.0) * upper
    moved[:, 2] += ramp * (height_mm - GAP_MM)
    return moved


def test_the_two_sheets_of_a_fold_face_each_other_and_the_template_pays_nothing():
    vertices, faces, upper = folded_strip()
    sheets = facing_sheets(vertices, faces)
    assert len(sheets) > 100
    # every pair joins the two sheets (none within one sheet, whatever its reach)
    assert np.all(upper[sheets.i] != upper[sheets.j])
    assert sheets.margin_mm.max() == pytest.approx(0.3)
    assert len(sheet_terms(sheets, vertices, faces)[0]) == 0


def test_a_sheet_pushed_through_the_other_presses_by_how_far_it_went_through():
    vertices, faces, upper = folded_strip()
    sheets = facing_sheets(vertices, faces)
    pushed = lowered(vertices, upper, -1.0)   # the upper sheet's far end now 1 mm below the lower sheet
    assert len(self_intersecting_faces(pushed, faces)) > 0
    pressing, residual, normals = sheet_terms(sheets, pushed, faces)
    assert len(pressing) > 0
    # over the flat far end the shortfall is the 1 mm through the other sheet and the 0.3 mm margin
    flat = (vertices[sheets.i[pressing], 0] < 5.5) & (vertices[sheets.j[pressing], 0] < 5.5)
    assert flat.sum() > 100 and residual[flat] == pytest.approx(1.3, abs=0.01)
    # a sheet lifted away from the other presses nowhere
    lifted = vertices.copy()
    lifted[upper, 2] += 2.0
    assert len(sheet_terms(sheets, lifted, faces)[0]) == 0


def test_moving_along_minus_the_residual_s_gradient_clears_the_pressing_pairs():
    vertices, faces, upper = folded_strip()
    sheets = facing_sheets(vertices, faces)
    pressed = lowered(vertices, upper, 0.1)   # the upper sheet's far end 0.1 mm over the lower one: within the margin
    pressing, residual, normals = sheet_terms(sheets, pressed, faces)
    flat = (vertices[sheets.i[pressing], 0] < 5.5) & (vertices[sheets.j[pressing], 0] < 5.5)
    assert flat.sum() > 100 and residual[flat] == pytest.approx(0.2, abs=0.01)
    # the residual's derivative by v_i is -side * n_j: a step against it moves each pressing vertex away
    step = np.zeros_like(pressed)
    np.add.at(step, sheets.i[pressing], (sheets.side[pressing] * residual)[:, None] * normals)
    counts = np.bincount(sheets.i[pressing], minlength=len(pressed))[:, None]
    cleared = pressed + step / np.maximum(counts, 1)
    assert len(sheet_terms(sheets, cleared, faces)[0]) < len(pressing) / 4
