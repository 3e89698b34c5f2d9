"""The configuration reference page, generated from ``config/schema.yaml`` (types, limits, meanings) and
``config/config.yaml`` (the shipped values), so that it cannot drift from the schema the workflow validates against.

Run ``python -m pipeline.config_reference`` to print the page; the documentation build writes it to
``reference/configuration.md`` (``docs/gen_pages.py``).
"""
from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = ROOT / "config" / "schema.yaml"
CONFIG = ROOT / "config" / "config.yaml"

_LIMITS = (("minimum", "≥ {}"), ("exclusiveMinimum", "> {}"), ("maximum", "≤ {}"), ("exclusiveMaximum", "< {}"),
           ("minItems", "at least {} items"), ("maxItems", "at most {} items"))


def schema_keys(schema: dict, prefix: str = "") -> Iterator[tuple[str, dict]]:
    """(dotted key, its schema) for every key the schema defines, depth first; the items of a list of objects as
    ``key[].item``."""
    for name, spec in (schema.get("properties") or {}).items():
        key = f"{prefix}{name}"
        yield key, spec
        if spec.get("properties"):
            yield from schema_keys(spec, f"{key}.")
        items = spec.get("items")
        if isinstance(items, dict) and items.get("properties"):
            yield from schema_keys(items, f"{key}[].")


def _shipped(config: dict, key: str):
    value = config
    for part in key.split("."):
        if part.endswith("[]") or not isinstance(value, dict) or part not in value:
            return None
        value = value[part]
    return value


def _type(spec: dict) -> str:
    kind = spec.get("type", "any")
    text = " or ".join(kind) if isinstance(kind, list) else kind
    if "enum" in spec:
        text += ": " + ", ".join(f"`{json.dumps(v)}`" for v in spec["enum"])
    limits = [fmt.format(spec[word]) for word, fmt in _LIMITS if word in spec]
    return text + (f" ({', '.join(limits)})" if limits else "")


def _value(value) -> str:
    if value is None:
        return ""
    text = json.dumps(value, ensure_ascii=False)
    return f"`{text}`" if len(text) <= 60 else f"`{text[:57]}...`"


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|").replace("<", "&lt;").replace(">", "&gt;")


def reference_page(schema_path: Path = SCHEMA, config_path: Path = CONFIG) -> str:
    """The Markdown page: one table per top-level section, every key with its type and limits, the schema's
    default, the value ``config/config.yaml`` ships, and its meaning."""
    schema = yaml.safe_load(schema_path.read_text())
    config = yaml.safe_load(config_path.read_text())
    lines = ["# Configuration reference", "",
             "Generated from `config/schema.yaml` (the schema every run is validated against) and "
             "`config/config.yaml` (the values the project ships); do not edit by hand. Give your own values in a "
             "file of your own (`snakemake --configfile my.yaml`, nested keys as in `config/config.yaml`) or, for "
             "top-level keys, on the command line (`snakemake --config data_root=...`). Keys are dotted paths; "
             "`key[].item` is a key of every item of a list.", ""]
    top_level = [(key, spec) for key, spec in schema_keys(schema) if "." not in key and "[]" not in key]
    plain = [(key, spec) for key, spec in top_level if not spec.get("properties")]
    general = [row for key, spec in plain
               for row in [(key, spec)] + [(k, s) for k, s in schema_keys(schema) if k.startswith(f"{key}[].")]]
    sections = [("General", "The dataset, the subjects and the new listeners of a run.", general)]
    for section, spec in top_level:
        if spec.get("properties"):
            sections.append((f"`{section}`", spec.get("description", ""),
                             [(key, inner) for key, inner in schema_keys(schema) if key.startswith(f"{section}.")]))
    for title, description, rows in sections:
        lines += [f"## {title}", "", _cell(description), "",
                  "| key | type | schema default | shipped | meaning |", "|---|---|---|---|---|"]
        for key, spec in rows:
            lines.append(f"| `{key}` | {_cell(_type(spec))} | {_value(spec.get('default'))} | "
                         f"{_value(_shipped(config, key))} | {_cell(spec.get('description', ''))} |")
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    print(reference_page())
