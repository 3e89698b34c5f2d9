# Reports: one self-contained HTML page per subject and one for the dataset (with a summary CSV).


rule report_subject:
    input:
        unpack(subject_report_inputs),
    output:
        html="results/{subject}/report.html",
        figures=directory("results/{subject}/report_figures"),
    log:
        "logs/report/report_subject/{subject}.log",
    benchmark:
        "benchmarks/timings/report/report_subject/{subject}.tsv"
    threads: 1
    resources:
        mem_mb=measured_mem_mb("report_subject"),
        runtime=measured_runtime("report_subject"),
    script:
        "../workflow/scripts/report_subject.py"


rule report_dataset:
    input:
        unpack(dataset_report_inputs),
    output:
        html="results/dataset_report.html",
        csv="results/dataset_summary.csv",
        parameters="results/dataset_parameters.csv",
        figures=directory("results/dataset_figures"),
    log:
        "logs/report/report_dataset.log",
    benchmark:
        "benchmarks/timings/report/report_dataset/all.tsv"
    params:
        subjects=SUBJECTS,
    threads: 1
    resources:
        mem_mb=measured_mem_mb("report_dataset"),
        runtime=measured_runtime("report_dataset"),
    script:
        "../workflow/scripts/report_dataset.py"
