"""The workflow's own Python: what a run makes for which subjects (:mod:`pipeline.run_plan`, used by
``rules/common.smk``), and the generated parts of the documentation (config reference, rule graph, import layers).
Imports the stage packages, never the other way round."""
