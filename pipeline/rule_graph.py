"""The workflow's rule graph as Mermaid, from Snakemake itself (``--rulegraph mermaid-js``), for the README's
picture of the pipeline and the architecture page; the README's copy is checked against it by a test.

Run ``python -m pipeline.rule_graph`` to print it, ``--update README.md`` to rewrite the README's block between
the ``<!-- rule graph -->`` markers.
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BEGIN, END = "<!-- rule graph: python -m pipeline.rule_graph --update README.md -->", "<!-- end of rule graph -->"


def rule_edges(*snakemake_args: str, root: Path = ROOT) -> list[tuple[str, str]]:
    """(upstream rule, downstream rule) of every dependency in the DAG of a run (default: the demo), ``all``
    left out; sorted, so the picture does not depend on Snakemake's numbering."""
    out = subprocess.run([sys.executable, "-m", "snakemake", "--rulegraph", "mermaid-js", "--forceall", "--quiet",
                          "all", *snakemake_args], cwd=root, capture_output=True, text=True, check=True).stdout
    names = dict(re.findall(r"^\s*(id\d+)\[([^\]]+)\]", out, flags=re.M))
    edges = {(names[a], names[b]) for a, b in re.findall(r"^\s*(id\d+) --> (id\d+)", out, flags=re.M)}
    return sorted((a, b) for a, b in edges if "all" not in (a, b))


def mermaid(edges: list[tuple[str, str]]) -> str:
    """A left-to-right Mermaid flowchart of the edges."""
    return "\n".join(["flowchart LR"] + [f"    {a} --> {b}" for a, b in edges])


def readme_block(text: str) -> str:
    """The Mermaid source between the README's rule-graph markers."""
    inner = text.split(BEGIN, 1)[1].split(END, 1)[0]
    return inner.strip().removeprefix("```mermaid").removesuffix("```").strip()


def update_readme(path: Path, graph: str) -> None:
    text = path.read_text()
    head, rest = text.split(BEGIN, 1)
    tail = rest.split(END, 1)[1]
    path.write_text(f"{head}{BEGIN}\n```mermaid\n{graph}\n```\n{END}{tail}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--update", type=Path, help="rewrite this file's rule-graph block")
    args = parser.parse_args()
    graph = mermaid(rule_edges())
    if args.update:
        update_readme(args.update, graph)
    else:
        print(graph)
