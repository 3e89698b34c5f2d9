"""The NumCalc solve plan printed before a run: steps stored vs to solve, and solver hours estimated from the
committed step store (evaluation/sonicom/steps), whose ppm heads took 4.0-6.1 CPU hours each."""
from reporting.solve_plan import measured_step_seconds, plan_rows, plan_text

from conftest import ROOT

STORE = ROOT / "evaluation" / "sonicom" / "steps"


def test_plan_counts_stored_steps_and_estimates_the_rest_from_the_committed_store():
    measured = measured_step_seconds(STORE)
    assert set(measured) == set(range(1, 41))  # every step of the 40-frequency set has been solved somewhere
    # NumCalc iterates longest at the lowest frequencies and has the most work at the highest: both ends cost more
    # than the middle of the set
    middle = sorted(measured[s] for s in range(10, 31))[10]
    assert measured[1] > 2 * middle and measured[40] > 2 * middle
    rows = plan_rows(STORE, [("P039", "ppm"), ("S_new", "ppm")], 40, [1])
    stored, new = rows
    assert (stored["stored"], stored["to_solve"], stored["solver_hours"]) == (40, 0, 0.0)
    assert (new["stored"], new["to_solve"]) == (0, 40)
    assert 2.0 < new["solver_hours"] < 8.0
    assert abs(new["solver_hours"] - sum(measured.values()) / 3600.0) < 1e-9
    text = plan_text(rows, cores=2)
    assert "S_new ppm: 40 of 40 steps to solve (0 stored)" in text
    assert f"~{new['solver_hours'] / 2:.1f} h on 2 core(s)" in text


def test_plan_without_a_store_gives_no_estimate(tmp_path):
    rows = plan_rows(None, [("S1", "ppm")], 40, [1, 2])
    assert rows[0]["to_solve"] == 80 and rows[0]["solver_hours"] is None
    assert "no stored steps to estimate" in plan_text(rows, cores=2)
    assert measured_step_seconds(tmp_path / "missing") == {}
