# The dataset evaluation (config evaluation.folder): per subject and condition the target <-> model distances
# of the condition's solved head (its pinna after stitching and remeshing); then summary.csv, the ranking of every
# condition beside the non-individual sets (ranking.csv), the left-ear HRTFs of every condition, the paper's Figures 6
# and 7, an HTML report and a README, all in the evaluation folder (kept in the repository).


rule condition_distances:
    input:
        target="results/{subject}/target/pinna_target.ply",
        pinna=lambda wc: head_mesh_of(wc.subject, wc.condition),
    output:
        summary="results/{subject}/evaluation/{condition}/distances.json",
        points="results/{subject}/evaluation/{condition}/distances.npz",
    log:
        "logs/evaluation/condition_distances/{subject}_{condition}.log",
    benchmark:
        "benchmarks/timings/evaluation/condition_distances/{subject}_{condition}.tsv"
    wildcard_constraints:
        condition="|".join(["original", "ppm", *CONTROLS]),
    threads: 1
    resources:
        mem_mb=measured_mem_mb("condition_distances"),
        runtime=measured_runtime("condition_distances"),
    script:
        "../workflow/scripts/condition_distances.py"


if EVALUATION_FOLDER:

    rule evaluation_report:
        input:
            unpack(evaluation_report_inputs),
        output:
            summary=f"{EVALUATION_FOLDER}/summary.csv",
            regions=f"{EVALUATION_FOLDER}/regions.csv",
            ranking=f"{EVALUATION_FOLDER}/ranking.csv",
            html=f"{EVALUATION_FOLDER}/report.html",
            readme=f"{EVALUATION_FOLDER}/README.md",
            figure6=f"{EVALUATION_FOLDER}/figure6_distances.png",
            figure7=f"{EVALUATION_FOLDER}/figure7_qe_pe.png",
            sofa=directory(f"{EVALUATION_FOLDER}/sofa"),
            hard_scans=directory(f"{EVALUATION_FOLDER}/hard_scans"),
        log:
            "logs/evaluation/evaluation_report.log",
        benchmark:
            "benchmarks/timings/evaluation/evaluation_report/all.tsv"
        params:
            subjects=SUBJECTS,
            conditions={s: evaluation_conditions(s) for s in SUBJECTS},
            not_solved={s: RUN.not_solved(s) for s in SUBJECTS},
            store=config["hrtf"]["step_store"],
            ppm_stores={s: store_of(s, "ppm") for s in SUBJECTS},
            configfiles=EVALUATION_CONFIGFILES,
            outside_settings=EVALUATION_OUTSIDE_SETTINGS,
            nonindividual=config["evaluation"].get("nonindividual") or [],
        threads: 1
        resources:
            mem_mb=measured_mem_mb("evaluation_report"),
            runtime=measured_runtime("evaluation_report"),
        script:
            "../workflow/scripts/evaluation_report.py"
