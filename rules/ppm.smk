# Pictures and files of the default parametric pinna model.


rule render_ppm:
    output:
        picture="results/ppm/default_ppm.png",
        sheet="results/ppm/range_sheet.png",
        blend="results/ppm/default_ppm.blend",
        parameters="results/ppm/default_parameters.csv",
    log:
        "logs/ppm/render_ppm.log",
    benchmark:
        "benchmarks/timings/ppm/render_ppm/all.tsv"
    threads: 1
    resources:
        mem_mb=measured_mem_mb("render_ppm"),
        runtime=measured_runtime("render_ppm"),
    script:
        "../workflow/scripts/render_ppm.py"
