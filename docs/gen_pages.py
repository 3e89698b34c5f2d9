"""Pages generated at each documentation build (mkdocs-gen-files): the configuration reference from
config/schema.yaml, and the import layers read from the source."""
from pathlib import Path

import mkdocs_gen_files
import yaml

from pipeline.config_reference import reference_page
from pipeline.import_graph import LAYERS, cycles, module_graph, package_edges
from pipeline.rule_graph import mermaid, rule_edges

with mkdocs_gen_files.open("reference/configuration.md", "w") as page:
    page.write(reference_page())

graph = module_graph()
lines = ["# Import layers", "",
         "Generated from the source at each build (`pipeline/import_graph.py`; `tests/test_import_layers.py` fails on "
         "a cycle or an upward import). The packages from the bottom layer up: " + ", ".join(f"`{p}`" for p in LAYERS)
         + ". An arrow points from the importing package to the imported one.", "",
         "```mermaid", "flowchart BT"]
lines += [f"    {importer} --> {imported}" for importer, imported in sorted(package_edges(graph))]
lines += ["```", "", f"Module cycles: {len(cycles(graph))}.", "", "| package | imports | through |", "|---|---|---|"]
for (importer, imported), through in sorted(package_edges(graph).items()):
    shown = ", ".join(f"`{line}`" for line in through[:4]) + (f" and {len(through) - 4} more" if len(through) > 4 else "")
    lines.append(f"| `{importer}` | `{imported}` | {shown} |")
with mkdocs_gen_files.open("reference/imports.md", "w") as page:
    page.write("\n".join(lines) + "\n")

# the paper's graph needs its dataset (config data_root, ../shared/data/sonicom beside the checkout)
paper_root = Path(yaml.safe_load(Path("config/paper_sonicom.yaml").read_text())["data_root"])
paper = ("```mermaid\n" + mermaid(rule_edges("--configfile", "config/paper_sonicom.yaml")) + "\n```\n"
         if paper_root.is_dir() else f"Not drawn in this build: its dataset `{paper_root}` is not beside the checkout.\n")
with mkdocs_gen_files.open("reference/rule-graph.md", "w") as page:
    page.write("# Rule graphs\n\nDrawn by Snakemake at each build (`snakemake --rulegraph mermaid-js`, "
               "`pipeline/rule_graph.py`); an arrow points from a rule to the rule that uses its output.\n\n"
               "## The default run (the demo)\n\n```mermaid\n" + mermaid(rule_edges()) + "\n```\n\n"
               "## The paper's evaluation (`config/paper_sonicom.yaml`)\n\n" + paper)
