"""The README is a front page that links into the documentation, and the generated documentation parts cannot drift:
every config key is on the reference page, the README's pipeline picture is Snakemake's rule graph. (The site itself
is built with --strict by scripts/test.sh.)"""
import re
from pathlib import Path

import yaml

from pipeline.config_reference import SCHEMA, reference_page, schema_keys
from pipeline.rule_graph import mermaid, readme_block, rule_edges

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def test_every_schema_key_is_on_the_configuration_reference():
    page = reference_page()
    keys = [key for key, _ in schema_keys(yaml.safe_load(SCHEMA.read_text()))]
    assert len(keys) > 50
    missing = [key for key in keys if f"`{key}`" not in page]
    assert not missing, f"keys of config/schema.yaml missing from the reference page: {missing}"
    # a key's row carries its limits and the value config/config.yaml ships
    row = next(line for line in page.splitlines() if line.startswith("| `hrtf.max_iterations` "))
    assert "integer (≥ 10)" in row and "`250`" in row and "CGS iterations" in row


def test_the_readme_is_a_front_page_that_starts_with_the_two_commands():
    lines = README.read_text().splitlines()
    assert len(lines) <= 220, f"README.md has {len(lines)} lines; move detail into docs/"
    assert lines[2:6] == ["```bash", lines[3], lines[4], "```"]
    assert lines[3].startswith("bash scripts/run.sh") and lines[4].startswith("bash scripts/test.sh")


def test_the_readme_links_point_at_files_that_exist():
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README.read_text())
    local = [link for link in links if not link.startswith(("http://", "https://"))]
    assert local, "the README links into docs/"
    missing = [link for link in local if not (ROOT / link).exists()]
    assert not missing, f"README links to missing files: {missing}"


def test_the_readme_pipeline_picture_is_the_rule_graph():
    assert readme_block(README.read_text()) == mermaid(rule_edges()), (
        "the workflow's rules changed: run .venv/bin/python -m pipeline.rule_graph --update README.md")
