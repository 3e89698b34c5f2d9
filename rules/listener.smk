# A new listener (config listeners): the head scan brought into the project frame and closed, both pinnae cut out
# and fitted by the PPM (the right one mirrored: the PPM is a left ear), both fits stitched into the head and the
# head remeshed at both pinnae. Results in results/listeners/<name>/. Its HRTFs are solved by the rules of
# rules/hrtf.smk with the subject "listeners/<name>" and the variant "personal" (grid "full", both ears); in a
# validation run (listener.scanned_head) its head as scanned too, the variant "scanned".

# a listener's subject "listeners/<name>" also matches the dataset rules' results/{subject}/stitch, /remesh and report
ruleorder: listener_stitch > stitch
ruleorder: listener_remesh > remesh
ruleorder: listener_report > report_subject


rule listener_prepare:
    input:
        head=lambda wc: RUN.listener_head(wc.listener),
    output:
        head="results/listeners/{listener}/prepared/head.ply",
        left="results/listeners/{listener}/prepared/pinna_left_crop.ply",
        right="results/listeners/{listener}/prepared/pinna_right_crop.ply",
        frame="results/listeners/{listener}/prepared/frame.json",
    log:
        "logs/listener/prepare/{listener}.log",
    benchmark:
        "benchmarks/timings/listener/prepare/{listener}.tsv"
    threads: 1
    resources:
        mem_mb=measured_mem_mb("listener_prepare"),
        runtime=measured_runtime("listener_prepare"),
    script:
        "../workflow/scripts/listener_prepare.py"


rule listener_ear_scan:
    input:
        scan=lambda wc: RUN.listener_ear_scan(wc.listener, wc.side),
        crop="results/listeners/{listener}/prepared/pinna_{side}_crop.ply",
        frame="results/listeners/{listener}/prepared/frame.json",
    output:
        mesh="results/listeners/{listener}/prepared/ear_scan_{side}.ply",
        report="results/listeners/{listener}/prepared/ear_scan_{side}.json",
    log:
        "logs/listener/ear_scan/{listener}_{side}.log",
    benchmark:
        "benchmarks/timings/listener/ear_scan/{listener}_{side}.tsv"
    params:
        ear_scan_frame=lambda wc: RUN.listener_ear_scan_frame(wc.listener),
    threads: 1
    resources:
        mem_mb=measured_mem_mb("prepare_target"),
        runtime=measured_runtime("prepare_target"),
    script:
        "../workflow/scripts/listener_ear_scan.py"


rule listener_target:
    input:
        scan=lambda wc: RUN.listener_target_scan(wc.listener, wc.side),
    output:
        target="results/listeners/{listener}/target/{side}/pinna_target.ply",
        report="results/listeners/{listener}/target/{side}/target.json",
        scan="results/listeners/{listener}/target/{side}/scan_in_frame.ply",
    log:
        "logs/listener/target/{listener}_{side}.log",
    benchmark:
        "benchmarks/timings/listener/target/{listener}_{side}.tsv"
    params:
        settings=lambda wc: {**config["align"], "scan_pose": "project_frame"},
        side=lambda wc: wc.side,
    threads: 1
    resources:
        mem_mb=measured_mem_mb("prepare_target"),
        runtime=measured_runtime("prepare_target"),
    script:
        "../workflow/scripts/prepare_target.py"


rule listener_align:
    input:
        target="results/listeners/{listener}/target/{side}/pinna_target.ply",
        scan="results/listeners/{listener}/target/{side}/scan_in_frame.ply",
        template=lambda wc: RUN.listener_template(),
    output:
        parameters_csv="results/listeners/{listener}/align/{side}/parameters.csv",
        parameters_json="results/listeners/{listener}/align/{side}/parameters.json",
        aligned="results/listeners/{listener}/align/{side}/aligned_pinna.ply",
        blend="results/listeners/{listener}/align/{side}/aligned_pinna.blend",
        distances="results/listeners/{listener}/align/{side}/distances.ply",
        summary="results/listeners/{listener}/align/{side}/summary.json",
        picture="results/listeners/{listener}/align/{side}/distance_map.png",
    log:
        "logs/listener/align/{listener}_{side}.log",
    benchmark:
        "benchmarks/timings/listener/align/{listener}_{side}.tsv"
    params:
        title=lambda wc: f"{wc.listener} {wc.side} ear",
    threads: 1
    resources:
        mem_mb=measured_mem_mb("align_ppm"),
        runtime=measured_runtime("align_ppm"),
    script:
        "../workflow/scripts/align_ppm.py"


# config listener.personal_detail: the personal-detail layer on a fit, towards the trusted parts of its ear scan
rule listener_detail:
    input:
        target="results/listeners/{listener}/target/{side}/pinna_target.ply",
        # the layer's evidence: the whole prepared scan of the ear, not only the pinna cut out for the fit
        evidence=lambda wc: RUN.listener_target_scan(wc.listener, wc.side),
        blend="results/listeners/{listener}/align/{side}/aligned_pinna.blend",
    output:
        aligned="results/listeners/{listener}/detail/{side}/aligned_pinna.ply",
        blend="results/listeners/{listener}/detail/{side}/aligned_pinna.blend",
        summary="results/listeners/{listener}/detail/{side}/summary.json",
        picture="results/listeners/{listener}/detail/{side}/distance_map.png",
    log:
        "logs/listener/detail/{listener}_{side}.log",
    benchmark:
        "benchmarks/timings/listener/detail/{listener}_{side}.tsv"
    params:
        title=lambda wc: f"{wc.listener} {wc.side} ear",
        side=lambda wc: wc.side,
        # config listener.personal_detail_settings: the layer's settings that differ from the packaged ones
        detail_settings=RUN.listener_detail_settings,
    threads: 1
    resources:
        mem_mb=measured_mem_mb("personal_detail"),
        runtime=measured_runtime("personal_detail"),
    script:
        "../workflow/scripts/personal_detail.py"


rule listener_stitch:
    input:
        head="results/listeners/{listener}/prepared/head.ply",
        pinna=lambda wc: RUN.listener_pinna(wc.listener, "left"),
        right_pinna=lambda wc: RUN.listener_pinna(wc.listener, "right"),
    output:
        mesh="results/listeners/{listener}/stitch/stitched_head.ply",
        report="results/listeners/{listener}/stitch/stitch.json",
    log:
        "logs/listener/stitch/{listener}.log",
    benchmark:
        "benchmarks/timings/listener/stitch/{listener}.tsv"
    params:
        gap_mm=lambda wc: config["stitch"]["gap_mm"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("stitch"),
        runtime=measured_runtime("stitch"),
    script:
        "../workflow/scripts/stitch_head.py"


rule listener_remesh:
    input:
        mesh="results/listeners/{listener}/stitch/stitched_head.ply",
        pinna=lambda wc: RUN.listener_pinna(wc.listener, "left"),
        right_pinna=lambda wc: RUN.listener_pinna(wc.listener, "right"),
    output:
        mesh="results/listeners/{listener}/remesh/head.ply",
        report="results/listeners/{listener}/remesh/validation.json",
    log:
        "logs/listener/remesh/{listener}.log",
    benchmark:
        "benchmarks/timings/listener/remesh/{listener}.tsv"
    params:
        bands=lambda wc: config["stitch"]["bands"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("remesh"),
        runtime=measured_runtime("remesh"),
    script:
        "../workflow/scripts/remesh_head.py"


# config listener.scanned_head (a validation run): the head as scanned, both ears unchanged, remeshed at both ears
# exactly as the personal head (refined where the PPM fits lie, not over the whole crop); solved as the HRTF
# variant "scanned", the paper protocol's reference and template
rule listener_scanned_head:
    input:
        mesh="results/listeners/{listener}/prepared/head.ply",
        pinna="results/listeners/{listener}/align/left/aligned_pinna.ply",
        right_pinna="results/listeners/{listener}/align/right/aligned_pinna.ply",
    output:
        mesh="results/listeners/{listener}/scanned/head.ply",
        report="results/listeners/{listener}/scanned/validation.json",
    log:
        "logs/listener/scanned_head/{listener}.log",
    benchmark:
        "benchmarks/timings/listener/scanned_head/{listener}.tsv"
    params:
        bands=lambda wc: config["stitch"]["bands"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("remesh"),
        runtime=measured_runtime("remesh"),
    script:
        "../workflow/scripts/remesh_head.py"


# what each ear's scan saw, per region of its fitted pinna, with advice: made before any solve, so that a listener
# can rescan an ear before hours of NumCalc are spent on a head built from a blind scan
rule listener_coverage:
    input:
        # the fitted (stitched) pinnae, their whole scans (the layer's evidence), the template's landmarks
        pinnae=lambda wc: [RUN.listener_pinna(wc.listener, side) for side in ("left", "right")],
        scans=lambda wc: [RUN.listener_target_scan(wc.listener, side) for side in ("left", "right")],
        landmarks=lambda wc: str(Path(RUN.listener_template()).parent / "landmarks.yaml"),
    output:
        coverage="results/listeners/{listener}/coverage.json",
        pictures=expand("results/listeners/{{listener}}/coverage_{side}.png", side=("left", "right")),
    log:
        "logs/listener/coverage/{listener}.log",
    benchmark:
        "benchmarks/timings/listener/coverage/{listener}.tsv"
    threads: 1
    resources:
        mem_mb=measured_mem_mb("localisation"),
        runtime=measured_runtime("localisation"),
    script:
        "../workflow/scripts/listener_coverage.py"


rule listener_report:
    input:
        frame="results/listeners/{listener}/prepared/frame.json",
        fits=lambda wc: [RUN.listener_pinna(wc.listener, side).replace("aligned_pinna.ply", "summary.json")
                         for side in ("left", "right")],
        remesh="results/listeners/{listener}/remesh/validation.json",
        hrtf="results/listeners/{listener}/hrtf/personal/HRTF.sofa",
        others=lambda wc: list(RUN.listener_comparisons(wc.listener).values()),
        coverage="results/listeners/{listener}/coverage.json",
    output:
        html="results/listeners/{listener}/report.html",
        planes="results/listeners/{listener}/hrtf_planes.png",
        localisation="results/listeners/{listener}/localisation.json",
    log:
        "logs/listener/report/{listener}.log",
    benchmark:
        "benchmarks/timings/listener/report/{listener}.tsv"
    params:
        others=lambda wc: RUN.listener_comparison_sets(wc.listener),
        calibration_grid=(config.get("listener") or {}).get("dataset_grid") or None,
        personal_detail=RUN.listener_personal_detail,
    threads: 1
    resources:
        mem_mb=measured_mem_mb("localisation"),
        runtime=measured_runtime("localisation"),
    script:
        "../workflow/scripts/listener_report.py"
