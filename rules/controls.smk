# The evaluation's control conditions (config evaluation.conditions), each a head solved like the PPM head:
# own_pinna, the head's own left pinna cut out and put back through the same stitch and remesh path (the
# pipeline's error floor); default_ppm, the template at default parameters placed by the global pose only
# (what the alignment buys); ppm_detail, the PPM fit with its personal-detail layer (ppm/align/detail.py);
# ppm_hard, ppm_detail_hard and nricp_hard, the same from one fixed defective scan (and free-form NRICP).


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


rule personal_detail:
    input:
        target=detail_target,
        # the layer's evidence: the whole scan (the clean crop or the fixed hard scan), not only the pinna the fit
        # was cut to
        evidence=detail_evidence,
        blend=lambda wc: f"results/{wc.subject}/{'controls/ppm_hard/' if wc.detailed == 'ppm_detail_hard' else ''}align/aligned_pinna.blend",
    output:
        aligned="results/{subject}/controls/{detailed}/align/aligned_pinna.ply",
        blend="results/{subject}/controls/{detailed}/align/aligned_pinna.blend",
        summary="results/{subject}/controls/{detailed}/align/summary.json",
        picture="results/{subject}/controls/{detailed}/align/distance_map.png",
    log:
        "logs/controls/personal_detail/{subject}_{detailed}.log",
    benchmark:
        "benchmarks/timings/controls/personal_detail/{subject}_{detailed}.tsv"
    wildcard_constraints:
        detailed="ppm_detail|ppm_detail_hard",
    params:
        side="left",
    threads: 1
    resources:
        mem_mb=measured_mem_mb("personal_detail"),
        runtime=measured_runtime("personal_detail"),
    script:
        "../workflow/scripts/personal_detail.py"


# The *_hard conditions start from one fixed defective scan of the clean crop (evaluation.hard_scan), kept with
# the evaluation's results; their distances are measured against the clean crop, the truth.
rule hard_scan:
    input:
        crop=lambda wc: str(DATA_ROOT / wc.subject / "pinna_left_crop.ply"),
    output:
        scan="results/{subject}/controls/hard/scan.ply",
        report="results/{subject}/controls/hard/scan.json",
    log:
        "logs/controls/hard_scan/{subject}.log",
    benchmark:
        "benchmarks/timings/controls/hard_scan/{subject}.tsv"
    params:
        settings=lambda wc: config["evaluation"]["hard_scan"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("hard_scan"),
        runtime=measured_runtime("hard_scan"),
    script:
        "../workflow/scripts/hard_scan.py"


rule hard_target:
    input:
        scan="results/{subject}/controls/hard/scan.ply",
    output:
        target="results/{subject}/controls/hard/target/pinna_target.ply",
        report="results/{subject}/controls/hard/target/target.json",
        scan="results/{subject}/controls/hard/target/scan_in_frame.ply",
    log:
        "logs/controls/hard_target/{subject}.log",
    benchmark:
        "benchmarks/timings/controls/hard_target/{subject}.tsv"
    params:
        settings=lambda wc: {**config["align"], "scan_pose": "project_frame"},
    threads: 1
    resources:
        mem_mb=measured_mem_mb("prepare_target"),
        runtime=measured_runtime("prepare_target"),
    script:
        "../workflow/scripts/prepare_target.py"


rule align_hard:
    input:
        target="results/{subject}/controls/hard/target/pinna_target.ply",
        scan="results/{subject}/controls/hard/target/scan_in_frame.ply",
        template=align_template,
    output:
        parameters_csv="results/{subject}/controls/ppm_hard/align/parameters.csv",
        parameters_json="results/{subject}/controls/ppm_hard/align/parameters.json",
        aligned="results/{subject}/controls/ppm_hard/align/aligned_pinna.ply",
        blend="results/{subject}/controls/ppm_hard/align/aligned_pinna.blend",
        distances="results/{subject}/controls/ppm_hard/align/distances.ply",
        summary="results/{subject}/controls/ppm_hard/align/summary.json",
        picture="results/{subject}/controls/ppm_hard/align/distance_map.png",
    log:
        "logs/controls/align_hard/{subject}.log",
    benchmark:
        "benchmarks/timings/controls/align_hard/{subject}.tsv"
    threads: 1
    resources:
        mem_mb=measured_mem_mb("align_ppm"),
        runtime=measured_runtime("align_ppm"),
    script:
        "../workflow/scripts/align_ppm.py"


rule nricp_hard:
    input:
        target="results/{subject}/controls/hard/target/pinna_target.ply",
        template=align_template,
    output:
        aligned="results/{subject}/controls/nricp_hard/align/aligned_pinna.ply",
        summary="results/{subject}/controls/nricp_hard/align/summary.json",
        picture="results/{subject}/controls/nricp_hard/align/distance_map.png",
    log:
        "logs/controls/nricp_hard/{subject}.log",
    benchmark:
        "benchmarks/timings/controls/nricp_hard/{subject}.tsv"
    threads: 1
    resources:
        mem_mb=measured_mem_mb("nricp_hard"),
        runtime=measured_runtime("nricp_hard"),
    script:
        "../workflow/scripts/nricp_fit.py"


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


# scan_hard: the fixed defective scan itself made watertight as a careful user would (outlier removal and screened
# Poisson reconstruction in pymeshlab, stitching/data/scan_reconstruction.yaml), cut under the rim of ppm_hard's
# pinna so that it replaces the same region of the head; then stitched, remeshed and solved like every condition.
rule scan_hard_pinna:
    input:
        scan="results/{subject}/controls/hard/scan.ply",
        guide="results/{subject}/controls/ppm_hard/align/aligned_pinna.ply",
    output:
        pinna="results/{subject}/controls/scan_hard/pinna.ply",
        surface="results/{subject}/controls/scan_hard/reconstruction.ply",
        report="results/{subject}/controls/scan_hard/reconstruction.json",
    log:
        "logs/controls/scan_hard_pinna/{subject}.log",
    benchmark:
        "benchmarks/timings/controls/scan_hard_pinna/{subject}.tsv"
    threads: 1
    resources:
        mem_mb=measured_mem_mb("scan_hard_pinna"),
        runtime=measured_runtime("scan_hard_pinna"),
    script:
        "../workflow/scripts/scan_pinna.py"
