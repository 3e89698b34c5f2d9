# The evaluation's control conditions (config evaluation.conditions), each a head solved like the PPM head:
# own_pinna, the head's own left pinna cut out and put back through the same stitch and remesh path (the
# pipeline's error floor); default_ppm, the template at default parameters placed by the global pose only
# (what the alignment buys).


rule own_pinna_region:
    input:
        head=lambda wc: str(DATA_ROOT / wc.subject / config["hrtf"]["reference_head"]),
        pinna="results/{subject}/align/aligned_pinna.ply",
    output:
        pinna="results/{subject}/controls/own_pinna/pinna.ply",
        report="results/{subject}/controls/own_pinna/region.json",
    log:
        "logs/controls/own_pinna_region/{subject}.log",
    benchmark:
        "benchmarks/timings/controls/own_pinna_region/{subject}.tsv"
    threads: 1
    resources:
        mem_mb=measured_mem_mb("own_pinna_region"),
        runtime=measured_runtime("own_pinna_region"),
    script:
        "../workflow/scripts/own_pinna.py"


rule place_default_ppm:
    input:
        target="results/{subject}/target/pinna_target.ply",
        template=align_template,
    output:
        aligned="results/{subject}/controls/default_ppm/align/aligned_pinna.ply",
        parameters_json="results/{subject}/controls/default_ppm/align/parameters.json",
        summary="results/{subject}/controls/default_ppm/align/summary.json",
        picture="results/{subject}/controls/default_ppm/align/distance_map.png",
    log:
        "logs/controls/place_default_ppm/{subject}.log",
    benchmark:
        "benchmarks/timings/controls/place_default_ppm/{subject}.tsv"
    params:
        global_pose_only=True,
    threads: 1
    resources:
        mem_mb=measured_mem_mb("place_default_ppm"),
        runtime=measured_runtime("place_default_ppm"),
    script:
        "../workflow/scripts/align_ppm.py"


rule stitch_control:
    input:
        head=lambda wc: str(DATA_ROOT / wc.subject / config["hrtf"]["reference_head"]),
        pinna=control_pinna,
    output:
        mesh="results/{subject}/controls/{control}/stitched_head.ply",
        report="results/{subject}/controls/{control}/stitch.json",
    log:
        "logs/controls/stitch/{subject}_{control}.log",
    benchmark:
        "benchmarks/timings/controls/stitch/{subject}_{control}.tsv"
    params:
        gap_mm=lambda wc: config["stitch"]["gap_mm"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("stitch"),
        runtime=measured_runtime("stitch"),
    script:
        "../workflow/scripts/stitch_head.py"


rule remesh_control:
    input:
        mesh="results/{subject}/controls/{control}/stitched_head.ply",
        pinna=control_pinna,
    output:
        mesh="results/{subject}/controls/{control}/head.ply",
        report="results/{subject}/controls/{control}/validation.json",
    log:
        "logs/controls/remesh/{subject}_{control}.log",
    benchmark:
        "benchmarks/timings/controls/remesh/{subject}_{control}.tsv"
    params:
        bands=lambda wc: config["stitch"]["bands"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("remesh"),
        runtime=measured_runtime("remesh"),
    script:
        "../workflow/scripts/remesh_head.py"
