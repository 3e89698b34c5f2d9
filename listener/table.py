"""The listeners of a run (config ``listeners``): each a name, a head scan and optionally separate scans of its
ears, checked before anything runs."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ppm.mesh_io import MESH_SUFFIXES

from .errors import ListenerError


@dataclass(frozen=True)
class Listener:
    """A new listener: its head scan and, by side ('left'/'right'), separate scans of its ears. ``ear_scan_frame``:
    ``"any"`` (the ear scans are in any pose and unit and are registered onto the head's ears) or ``"head"`` (they
    share the head scan's coordinates and unit, as the scans of one session do, and are placed by the head's frame)."""

    name: str
    head: Path
    ear_scans: dict[str, Path] = field(default_factory=dict)
    ear_scan_frame: str = "any"


#: How a listener's separate ear scans are brought onto its head (config listeners: ear_scan_frame).
EAR_SCAN_FRAMES = ("any", "head")


def _checked(path: str, what: str, name: str) -> Path:
    path = Path(path)
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise ListenerError(f"config listeners ({name}): {path} is not a mesh file; give a PLY, STL or OBJ {what}")
    if not path.is_file() or path.stat().st_size == 0:
        raise ListenerError(f"config listeners ({name}): {path} is missing or empty; give the path of the {what} "
                            "(relative to the folder snakemake runs in)")
    return path


def listeners_of(config: dict) -> dict[str, Listener]:
    """Name -> :class:`Listener` of config ``listeners`` (in the order given).

    Raises
    ------
    ListenerError
        If a name repeats, a scan is missing, empty or not PLY/STL/OBJ, or ear_scan_frame is unknown.
    """
    listeners: dict[str, Listener] = {}
    for entry in config.get("listeners") or []:
        name = entry["name"]
        if name in listeners:
            raise ListenerError(f"config listeners: the name {name!r} is given twice; give each listener its own name")
        ears = {side: _checked(entry[f"{side}_ear"], f"scan of the {side} ear", name)
                for side in ("left", "right") if entry.get(f"{side}_ear")}
        frame = str(entry.get("ear_scan_frame") or "any")
        if frame not in EAR_SCAN_FRAMES:
            raise ListenerError(f"config listeners ({name}): ear_scan_frame is {frame!r}; give 'any' (ear scans in any "
                                "pose, registered onto the head's ears) or 'head' (ear scans in the head scan's own "
                                "coordinates and unit)")
        listeners[name] = Listener(name, _checked(entry["head"], "head scan", name), ears, frame)
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
