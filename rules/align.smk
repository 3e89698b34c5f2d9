# Automatic alignment of the PPM to each subject's left pinna scan, with a template that never saw
# that subject (leave-one-subject-out).


rule prepare_target:
    input:
        scan=lambda wc: str(DATA_ROOT / wc.subject / "pinna_left_crop.ply"),
    output:
        target="results/{subject}/target/pinna_target.ply",
        report="results/{subject}/target/target.json",
        scan="results/{subject}/target/scan_in_frame.ply",
    log:
        "logs/align/prepare_target/{subject}.log",
    benchmark:
        "benchmarks/timings/align/prepare_target/{subject}.tsv"
    params:
        settings=lambda wc: config["align"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("prepare_target"),
        runtime=measured_runtime("prepare_target"),
    script:
        "../workflow/scripts/prepare_target.py"


rule align_ppm:
    input:
        target="results/{subject}/target/pinna_target.ply",
        report="results/{subject}/target/target.json",
        scan="results/{subject}/target/scan_in_frame.ply",
        template=align_template,
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
    threads: 1
    resources:
        mem_mb=measured_mem_mb("align_ppm"),
        runtime=measured_runtime("align_ppm"),
    script:
        "../workflow/scripts/align_ppm.py"
