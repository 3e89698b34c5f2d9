# HRTFs of head meshes: Mesh2HRTF project export, solving (NumCalc one job per ear and range of
# frequency steps, hrtf.steps_per_job long, or the embedded solver one job per subject for all its heads, so
# that numba compiles bempp-cl's kernels once), and
# collection into SOFA files.
# Variants: "reference" = the dataset's ground-truth head (<subject>/head_graded_left.ply); "ppm" = the head
# with the aligned PPM stitched in; the controls "own_pinna" and "default_ppm" (rules/controls.smk).
# A head of hrtf.frequency_bands.variants is solved with NumCalc on a mesh per frequency band: band_head remeshes it
# coarser (the ear-canal sources kept), export_band_project exports that mesh with the whole frequency set, the
# steps of each band are solved in its project, and collect_sofa merges them into the full project's results.


rule export_project:
    input:
        unpack(hrtf_export_inputs),
    output:
        project=directory("results/{subject}/hrtf/{variant}/project"),
    log:
        "logs/hrtf/export_project/{subject}_{variant}.log",
    benchmark:
        "benchmarks/timings/hrtf/export_project/{subject}_{variant}.tsv"
    params:
        settings=lambda wc: RUN.export_settings(wc.subject),
        title=lambda wc: f"{wc.subject}_{wc.variant}".replace("/", "_"),
        head_store=lambda wc: store_of(wc.subject, wc.variant) if wc.variant in BUILT_HEADS else None,
    threads: 1
    resources:
        mem_mb=measured_mem_mb("export_project"),
        runtime=measured_runtime("export_project"),
    script:
        "../workflow/scripts/export_project.py"


rule band_head:
    input:
        unpack(band_head_inputs),
    output:
        mesh="results/{subject}/hrtf/{variant}/band_{band}/head.ply",
        sources="results/{subject}/hrtf/{variant}/band_{band}/sources.json",
    log:
        "logs/hrtf/band_head/{subject}_{variant}_{band}.log",
    benchmark:
        "benchmarks/timings/hrtf/band_head/{subject}_{variant}_{band}.tsv"
    params:
        bands=lambda wc: RUN.band_remesh_bands(int(wc.band)),
        sides=lambda wc: ["left", "right"] if config["hrtf"]["ears"] == "both" else [config["hrtf"]["ears"]],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("remesh"),
        runtime=measured_runtime("remesh"),
    script:
        "../workflow/scripts/band_head.py"


rule export_band_project:
    input:
        unpack(band_export_inputs),
    output:
        project=directory("results/{subject}/hrtf/{variant}/band_{band}/project"),
    log:
        "logs/hrtf/export_band_project/{subject}_{variant}_{band}.log",
    benchmark:
        "benchmarks/timings/hrtf/export_band_project/{subject}_{variant}_{band}.tsv"
    params:
        settings=lambda wc: RUN.export_settings(wc.subject),
        title=lambda wc: f"{wc.subject}_{wc.variant}_band_{wc.band}".replace("/", "_"),
        head_store=lambda wc: RUN.band_store_of(wc.subject, wc.variant, int(wc.band)),
    threads: 1
    resources:
        mem_mb=measured_mem_mb("export_project"),
        runtime=measured_runtime("export_project"),
    script:
        "../workflow/scripts/export_project.py"


rule solve_numcalc_step:
    input:
        project=numcalc_step_project,
    output:
        status="results/{subject}/hrtf/{variant}/steps/source_{source}/steps_{first}-{last}.json",
    log:
        "logs/hrtf/solve_numcalc_step/{subject}_{variant}_{source}_{first}-{last}.log",
    benchmark:
        "benchmarks/timings/hrtf/solve_numcalc_step/{subject}_{variant}_{source}_{first}-{last}.tsv"
    params:
        numcalc=lambda wc: config["hrtf"]["numcalc"],
        max_iterations=lambda wc: config["hrtf"]["max_iterations"],
        store=numcalc_step_store,
    threads: 1
    resources:
        mem_mb=numcalc_step_mem_mb,
        runtime=numcalc_step_runtime_min,
    script:
        "../workflow/scripts/solve_numcalc_step.py"


rule solve_embedded:
    input:
        projects=lambda wc: [f"results/{wc.subject}/hrtf/{v}/project" for v in solved_variants(wc.subject)],
    output:
        status="results/{subject}/hrtf/embedded.json",
    log:
        "logs/hrtf/solve_embedded/{subject}.log",
    benchmark:
        "benchmarks/timings/hrtf/solve_embedded/{subject}.tsv"
    params:
        variants=lambda wc: solved_variants(wc.subject),
        stores=lambda wc: {v: store_of(wc.subject, v) for v in solved_variants(wc.subject)},
        device=config["hrtf"].get("embedded_device", "auto"),
    threads: config["hrtf"]["embedded_threads"]
    resources:
        mem_mb=embedded_mem_mb,
        runtime=embedded_runtime_min,
        gpu=embedded_gpus,
    script:
        "../workflow/scripts/solve_embedded.py"


rule collect_sofa:
    input:
        project="results/{subject}/hrtf/{variant}/project",
        bands=band_projects,
        steps=solved_steps,
    output:
        hrtf="results/{subject}/hrtf/{variant}/HRTF.sofa",
        hrir="results/{subject}/hrtf/{variant}/HRIR.sofa",
    log:
        "logs/hrtf/collect_sofa/{subject}_{variant}.log",
    params:
        hrir=lambda wc: config["hrtf"]["hrir"],
        band_steps=lambda wc: RUN.band_projects(wc.subject, wc.variant),
    benchmark:
        "benchmarks/timings/hrtf/collect_sofa/{subject}_{variant}.tsv"
    threads: 1
    resources:
        mem_mb=measured_mem_mb("collect_sofa"),
        runtime=measured_runtime("collect_sofa"),
    script:
        "../workflow/scripts/collect_sofa.py"
