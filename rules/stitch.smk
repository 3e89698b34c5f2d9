# The aligned PPM pinna on the subject's head: stitched in place of the head's own left pinna, then
# remeshed for BEM (1 mm at the pinna, graded coarser with distance).


rule stitch:
    input:
        head=lambda wc: str(DATA_ROOT / wc.subject / config["hrtf"]["reference_head"]),
        pinna="results/{subject}/align/aligned_pinna.ply",
    output:
        mesh="results/{subject}/stitch/stitched_head.ply",
        report="results/{subject}/stitch/stitch.json",
    log:
        "logs/stitch/stitch/{subject}.log",
    benchmark:
        "benchmarks/timings/stitch/stitch/{subject}.tsv"
    params:
        gap_mm=lambda wc: config["stitch"]["gap_mm"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("stitch"),
        runtime=measured_runtime("stitch"),
    script:
        "../workflow/scripts/stitch_head.py"


rule remesh:
    input:
        mesh="results/{subject}/stitch/stitched_head.ply",
        pinna="results/{subject}/align/aligned_pinna.ply",
    output:
        mesh="results/{subject}/remesh/head.ply",
        report="results/{subject}/remesh/validation.json",
    log:
        "logs/stitch/remesh/{subject}.log",
    benchmark:
        "benchmarks/timings/stitch/remesh/{subject}.tsv"
    params:
        bands=lambda wc: config["stitch"]["bands"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("remesh"),
        runtime=measured_runtime("remesh"),
    script:
        "../workflow/scripts/remesh_head.py"
