# Demo subjects, made when no dataset is configured (data_root empty): a PPM ear with random in-range
# parameters, its scan with noise, holes and outliers, and a parametric head wearing it (demo fidelity).


rule make_demo_subject:
    output:
        scan="results/demo_data/{subject}/pinna_left_crop.ply",
        head="results/demo_data/{subject}/head_graded_left.ply",
        truth="results/demo_data/{subject}/truth_parameters.json",
        description="results/demo_data/{subject}/demo.json",
    log:
        "logs/demo/make_demo_subject/{subject}.log",
    benchmark:
        "benchmarks/timings/demo/make_demo_subject/{subject}.tsv"
    params:
        seed=demo_seed,
        settings=lambda wc: config["demo"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("make_demo_subject"),
        runtime=measured_runtime("make_demo_subject"),
    script:
        "../workflow/scripts/make_demo_subject.py"
