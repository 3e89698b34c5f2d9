"""The listeners of a run (config ``listeners``): each a name and a head scan, checked before anything runs."""
from __future__ import annotations

from pathlib import Path

from ppm.mesh_io import MESH_SUFFIXES

from .errors import ListenerError


def listeners_of(config: dict) -> dict[str, Path]:
    """Name -> head scan path of config ``listeners`` (in the order given).

    Raises
    ------
    ListenerError
        If a name repeats, or a head scan is missing, empty or not PLY/STL/OBJ.
    """
    listeners: dict[str, Path] = {}
    for entry in config.get("listeners") or []:
        name, head = entry["name"], Path(entry["head"])
        if name in listeners:
            raise ListenerError(f"config listeners: the name {name!r} is given twice; give each listener its own name")
        if head.suffix.lower() not in MESH_SUFFIXES:
            raise ListenerError(f"config listeners ({name}): {head} is not a mesh file; give a PLY, STL or OBJ head scan")
        if not head.is_file() or head.stat().st_size == 0:
            raise ListenerError(f"config listeners ({name}): {head} is missing or empty; give the path of the head scan "
                                "(relative to the folder snakemake runs in)")
        listeners[name] = head
    return listeners


def listener_template(config: dict) -> str:
    """The template pinna both ears of a listener are fitted with: config ``listener.template``'s
    ``template_left.ply``, or the packaged template's."""
    folder = (config.get("listener") or {}).get("template") or ""
    if folder:
        path = Path(folder) / "template_left.ply"
        if not path.is_file():
            raise ListenerError(f"config listener.template: {path} is missing; give a folder holding template_left.ply "
                                "(a template built by this pipeline), or leave it empty for the packaged template")
        return str(path)
    from ppm.template.store import default_template_dir  # noqa: PLC0415

    return str(default_template_dir() / "template_left.ply")
