# Automatic alignment of the PPM to each subject's left pinna scan, with a template that never saw
# that subject (leave-one-subject-out).


rule align_ppm:
    input:
        scan=lambda wc: str(DATA_ROOT / wc.subject / "pinna_left_crop.ply"),
        template="results/templates/without_{subject}/template_left.ply",
    output:
        parameters_csv="results/{subject}/align/parameters.csv",
        parameters_json="results/{subject}/align/parameters.json",
        aligned="results/{subject}/align/aligned_pinna.ply",
        blend="results/{subject}/align/aligned_pinna.blend",
        distances="results/{subject}/align/distances.ply",
        summary="results/{subject}/align/summary.json",
        picture="results/{subject}/align/distance_map.png",
    log:
        "logs/align/align_ppm/{subject}.log",
    benchmark:
        "benchmarks/timings/align/align_ppm/{subject}.tsv"
    params:
        settings=lambda wc: config["align"],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=20,
    script:
        "../workflow/scripts/align_ppm.py"
