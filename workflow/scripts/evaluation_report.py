"""Rule evaluation_report: summary.csv, the left-ear HRTFs, Figures 6 and 7, the HTML page and the README of the
dataset evaluation (config evaluation.folder)."""
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
from _logging import configure_logging  # noqa: E402

configure_logging(snakemake)  # noqa: F821

from mesh2hrtf_io.frequency_sets import describe_set  # noqa: E402
from reporting.cost import subjects_timings  # noqa: E402
from reporting.kept_fit import subject_fit_landmarks  # noqa: E402
from reporting.paper_protocol import with_paper_columns  # noqa: E402
from reporting.evaluation import evaluation_rows  # noqa: E402
from reporting.evaluation_figures import figure6, figure7  # noqa: E402
from reporting.evaluation_files import (copy_hard_scans, copy_sofa, read_summary_csv, write_regions_csv,  # noqa: E402
                                        write_summary_csv)
from reporting.evaluation_pages import not_solved_lines, write_html, write_readme  # noqa: E402
from reporting.evaluation_regions import region_rows  # noqa: E402
from reporting.nonindividual import MeasuredSet, nonindividual_rows  # noqa: E402
from reporting.ranking import ranking_rows, read_ranking_csv, write_ranking_csv  # noqa: E402

inputs, out, params = snakemake.input, snakemake.output, snakemake.params  # noqa: F821
subjects, conditions = list(params.subjects), dict(params.conditions)
pairs = [(s, c) for s in subjects for c in conditions[s]]
heads = {(s, c): inputs[f"{s}_{c}_head"] for s, c in pairs}
steps = {(s, c): list(inputs[f"{s}_{c}_steps"]) for s, c in pairs}
steps = {key: [value] if isinstance(value, str) else value for key, value in steps.items()}
rows = evaluation_rows("results", subjects, conditions, heads, steps, params.store or None)
# the paper's protocol beside the dataset's: original as reference and template, S at 8 % QE on it
rows = with_paper_columns(rows, {(s, c): inputs[f"{s}_{c}_hrtf"] for s, c in pairs},
                          {s: inputs[f"{s}_reference"] for s in subjects})
frequencies = json.loads(Path(inputs[f"{subjects[0]}_localisation"]).read_text())["frequency_set"]["frequencies_hz"]
frequency_note = describe_set(frequencies)
write_summary_csv(out.summary, rows)
rows = read_summary_csv(out.summary)  # the figures and texts show the CSV's rounded numbers, not others
# what a listener would use otherwise, by the same protocol: the other subjects' original, the measured sets
measured = [MeasuredSet.from_config(entry) for entry in params.nonindividual]
originals = {s: inputs[f"{s}_original_hrtf"] for s in subjects if f"{s}_original_hrtf" in inputs.keys()}
nonindividual = nonindividual_rows(subjects, originals, {s: inputs[f"{s}_reference"] for s in subjects}, measured)
write_ranking_csv(out.ranking, ranking_rows(rows, nonindividual))
ranking = read_ranking_csv(out.ranking)
# the landmarks kept with each PPM head (reporting.kept_fit), else the alignment's (then kept with the head)
positions = {s: subject_fit_landmarks(params.ppm_stores[s], inputs.get(f"{s}_aligned"), inputs.get(f"{s}_landmarks"))
             for s in subjects}
regions = region_rows("results", subjects, conditions, positions)
write_regions_csv(out.regions, regions)
copy_sofa({(s, c): inputs[f"{s}_{c}_hrtf"] for s, c in pairs}, out.sofa)
copy_hard_scans({s: inputs[f"{s}_hard_scan"] for s in subjects if f"{s}_hard_scan" in inputs.keys()}, out.hard_scans)
figure7(rows, out.figure7)
figure6(Path("results"), subjects, conditions, out.figure6)
configfiles = list(params.configfiles)
outside = list(params.outside_settings)
not_solved = not_solved_lines(dict(params.not_solved))
write_html(out.html, rows, Path(out.figure6), Path(out.figure7), frequency_note, configfiles, regions, outside,
           not_solved, ranking)
timings = subjects_timings("benchmarks/timings", subjects)
wall_clock_h = sum(t.seconds for jobs in timings.values() for t in jobs) / 3600.0
write_readme(out.readme, rows, frequency_note, configfiles, wall_clock_h, regions, outside, not_solved, ranking)
