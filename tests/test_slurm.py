"""The workflow's cluster path on a real SLURM controller (scripts/local_slurm.sh: Debian's slurm-wlm with
slurmdbd, munge and MariaDB on this machine): the CI-sized demo with --profile profiles/slurm, every job
through sbatch, a running solve cancelled and resumed, no job above its memory or time request."""
from __future__ import annotations

import subprocess

import pytest

from reporting.slurm_accounting import duration_s, memory_mb, parse_sacct, rule_of, run_demo_on_slurm, summarise

from conftest import ROOT


def test_sacct_fields_parse():
    assert memory_mb("66192K") == pytest.approx(64.64, abs=0.01)
    assert memory_mb("3000M") == 3000.0 and memory_mb("2Gn") == 2048.0 and memory_mb("") is None
    assert duration_s("1-02:03:04") == 93784.0 and duration_s("05:00") == 300.0 and duration_s("UNLIMITED") is None
    assert rule_of("rule_solve_numcalc_step_wildcards_P039_ppm_1_3_3") == "solve_numcalc_step"
    assert rule_of("rule_render_ppm") == "render_ppm"
    summary = summarise([
        {"rule": "align_ppm", "state": "COMPLETED", "req_mem_mb": 3000.0, "max_rss_mb": 600.0, "time_limit_s": 1200.0,
         "elapsed_s": 60.0},
        {"rule": "align_ppm", "state": "OUT_OF_MEMORY", "req_mem_mb": 3000.0, "max_rss_mb": 3100.0,
         "time_limit_s": 1200.0, "elapsed_s": 30.0},
        {"rule": "stitch", "state": "CANCELLED", "req_mem_mb": 1000.0, "max_rss_mb": 0.0, "time_limit_s": 600.0,
         "elapsed_s": 5.0}])
    assert summary["jobs_submitted"] == 3 and summary["jobs_failed"] == 1 and summary["jobs_cancelled"] == 1
    assert summary["max_rss_over_request"] == pytest.approx(3100 / 3000, abs=1e-3)
    assert summary["per_rule"]["align_ppm"]["jobs"] == 2


def test_a_job_of_an_earlier_run_is_not_counted_as_this_runs(tmp_path):
    """A remesh job left running when an earlier run's cluster was stopped comes back as TIMEOUT once the cluster
    starts again (its start time is long past): sacct lists it within this run's window, from another folder."""
    here, earlier = tmp_path / "project", tmp_path / "earlier" / "project"
    text = "\n".join([
        f"7|run-a|rule_remesh_wildcards_demo01|TIMEOUT|2000M||00:10:03|00:10:00|{earlier}",
        "7.batch|batch||CANCELLED||431M|00:10:03||",
        f"12|run-b|rule_remesh_wildcards_demo01|COMPLETED|2000M||00:00:14|00:10:00|{here}",
        "12.batch|batch||COMPLETED||455M|00:00:14||",
        f"13|run-b|rule_stitch_wildcards_demo01|COMPLETED|1000M||00:00:09|00:10:00|{here}/",
    ])
    everything = parse_sacct(text)
    assert [job["state"] for job in everything] == ["TIMEOUT", "COMPLETED", "COMPLETED"]
    ours = parse_sacct(text, work_dir=here)
    assert [(job["job_id"], job["rule"]) for job in ours] == [("12", "remesh"), ("13", "stitch")]
    assert ours[0]["max_rss_mb"] == 455.0 and ours[0]["elapsed_s"] == 14.0
    assert summarise(ours)["jobs_failed"] == 0


def _packages_installable() -> str | None:
    """Why the Debian packages cannot be had here, or None."""
    probe = subprocess.run(["bash", "-c", "command -v sbatch || (command -v apt-get && [ \"$(id -u)\" = 0 ])"],
                           capture_output=True, text=True)
    return None if probe.returncode == 0 else "no SLURM installed and no apt-get as root to install slurm-wlm"


@pytest.mark.slow
@pytest.mark.alone
def test_the_demo_runs_through_a_real_slurm_controller(tmp_path):
    reason = _packages_installable()
    if reason:
        pytest.skip(reason)
    result = run_demo_on_slurm(ROOT, tmp_path / "project")
    rules = result["per_rule"]
    # every rule of the demo went through sbatch (the profile has no local rules)
    for rule in ("render_ppm", "make_demo_subject", "prepare_target", "align_ppm", "stitch", "remesh",
                 "export_project", "solve_embedded", "collect_sofa", "localisation", "report_subject", "report_dataset"):
        assert rule in rules, f"{rule} was not submitted to SLURM: {sorted(rules)}"
    assert result["jobs_failed"] == 0, rules
    # the solve was cancelled while running and resumed: its finished steps were not solved again
    assert result["resumed_after_scancel"] and result["jobs_cancelled"] == 1
    assert result["steps_solved_after_resume"] < 2 * 2 * 8  # 2 heads x 2 ears x 8 frequencies
    assert result["max_rss_over_request"] < 1.0 and result["max_elapsed_over_limit"] < 1.0
    for rule, row in rules.items():
        assert row["req_mem_mb"] and row["time_limit_s"], f"{rule}: no memory or time request"
    for name in ("results/dataset_report.html", "results/demo01/localisation/qe_pe.json",
                 "results/demo01/hrtf/ppm/HRIR.sofa", "results/ppm/default_ppm.png"):
        assert name in result["outputs"]
