# baumgartner2014: quadrant and polar errors predicted for the HRTFs of each solved condition (the PPM head,
# and the controls of config evaluation.conditions) heard with the reference listener's HRTFs as template,
# S calibrated on the reference (config localisation).


rule localisation:
    input:
        unpack(localisation_inputs),
    output:
        summary="results/{subject}/localisation/qe_pe.json",
        bars="results/{subject}/localisation/qe_pe_bars.png",
        reference_matrix="results/{subject}/localisation/reference_matrix.png",
        ppm_matrix="results/{subject}/localisation/ppm_matrix.png",
    log:
        "logs/localisation/{subject}.log",
    benchmark:
        "benchmarks/timings/localisation/localisation/{subject}.tsv"
    params:
        settings=lambda wc: config["localisation"],
        reference_frequencies=reference_frequencies,
        frequency_set=lambda wc: config["hrtf"]["frequencies_hz"],
        conditions=lambda wc: evaluation_conditions(wc.subject),
        solved_ear=lambda wc: None if config["hrtf"]["ears"] == "both" else config["hrtf"]["ears"],
    threads: 1
    resources:
        mem_mb=measured_mem_mb("localisation"),
        runtime=measured_runtime("localisation"),
    script:
        "../workflow/scripts/localisation.py"
