# Template pinna builds: the average left pinna of a dataset, leaving one subject out.


rule build_template:
    input:
        data_root=lambda wc: str(DATA_ROOT),
    output:
        mesh="results/templates/without_{subject}/template_left.ply",
        provenance="results/templates/without_{subject}/provenance.json",
        landmarks="results/templates/without_{subject}/landmarks.yaml",
    log:
        "logs/template/build_template/{subject}.log",
    benchmark:
        "benchmarks/timings/template/build_template/{subject}.tsv"
    params:
        settings=template_params(),
    threads: 1
    resources:
        mem_mb=measured_mem_mb("build_template"),
        runtime=measured_runtime("build_template"),
    script:
        "../workflow/scripts/build_template.py"
