"""Off-screen pictures of the PPM with pyvista: the posed model with its armature, and a sheet of
every curve and shape key at its range limits. Millimetres, project frame (+x front, +y left, +z up);
the lateral view looks at the left pinna from +y.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.atomic import atomic_path
from .model import PinnaModel, bone_polylines
from .parameters import PinnaParameters, model_layout, parameter_specs

CURVE_COLOURS = ("#e6194b", "#3cb44b", "#4363d8", "#f58231", "#911eb4", "#42d4f4", "#f032e6", "#9a6324", "#469990")


def _pyvista():
    import pyvista as pv  # noqa: PLC0415  (VTK is heavy: load it when a picture is made)

    pv.OFF_SCREEN = True
    return pv


def _polydata(pv, vertices_mm: np.ndarray, faces: np.ndarray):
    return pv.PolyData(vertices_mm, np.hstack([np.full((len(faces), 1), 3), faces]).ravel())


def _lateral_camera(plotter, vertices_mm: np.ndarray, distance_mm: float = 260.0) -> None:
    centre = vertices_mm.mean(axis=0)
    plotter.camera_position = [tuple(centre + [0.0, distance_mm, 0.0]), tuple(centre), (0.0, 0.0, 1.0)]
    plotter.camera.parallel_projection = True
    plotter.camera.parallel_scale = 0.55 * np.ptp(vertices_mm[:, 2])


def render_model(model: PinnaModel, path: str | os.PathLike, params: PinnaParameters | None = None,
                 size_px: tuple[int, int] = (1600, 800)) -> Path:
    """PNG of the posed PPM with its armature: lateral view (from +y) and a view from the front (+x)."""
    pv = _pyvista()
    vertices = model.evaluate(params)
    lines = bone_polylines(model)
    curves = model_layout()["curves"]
    plotter = pv.Plotter(off_screen=True, shape=(1, 2), window_size=size_px)
    for column, (eye, up) in enumerate((([0, 1, 0], [0, 0, 1]), ([1, 0, 0], [0, 0, 1]))):
        plotter.subplot(0, column)
        plotter.add_mesh(_polydata(pv, vertices, model.faces), color="tan", smooth_shading=True, opacity=0.55)
        for colour, curve in zip(CURVE_COLOURS, curves):
            bendy = lines[f"{curve}-Bendy"]
            plotter.add_mesh(pv.Spline(bendy, 60).tube(radius=0.5), color=colour)
            for end in ("Start", "End"):
                control = lines[f"{curve}-{end}"]
                plotter.add_mesh(pv.Line(control[0], control[-1]).tube(radius=0.35), color="black")
                plotter.add_mesh(pv.Sphere(radius=0.9, center=control[0]), color=colour)
        parent = lines[model_layout()["parent_bone"]]
        plotter.add_mesh(pv.Line(parent[0], parent[-1]).tube(radius=0.6), color="gray")
        centre = vertices.mean(axis=0)
        plotter.camera_position = [tuple(centre + 260.0 * np.array(eye)), tuple(centre), tuple(up)]
        plotter.camera.parallel_projection = True
        plotter.camera.parallel_scale = 0.55 * np.ptp(vertices[:, 2])
        plotter.add_text(["lateral view (from +y)", "front view (from +x)"][column], font_size=12)
    plotter.add_legend([(c, col) for c, col in zip(curves, CURVE_COLOURS)], bcolor="white", size=(0.28, 0.3),
                       loc="lower right")
    path = Path(path)
    with atomic_path(path) as tmp:
        plotter.screenshot(str(tmp))
    plotter.close()
    return path


def range_sheet_items() -> list[tuple[str, dict[str, float], dict[str, float]]]:
    """(title, lower-limit parameters, upper-limit parameters) for each curve and shape key.

    A curve is shown with both its control bones moved along their Z axis (the surface normal) to
    the ends of their typical spread between listeners (the alignment's bounds are wider); the parent
    curve with its isotropic size at the scale bounds; a shape key at its weight bounds.
    """
    specs = {s.name: s for s in parameter_specs()}
    layout = model_layout()
    parent = layout["parent_bone"]
    items = [(f"{parent} (scale)", {f"Scale_{parent}_{a}": specs[f"Scale_{parent}_{a}"].lower for a in "XYZ"},
              {f"Scale_{parent}_{a}": specs[f"Scale_{parent}_{a}"].upper for a in "XYZ"})]
    for curve in layout["curves"]:
        names = [f"Location_{curve}-{end}_Z" for end in ("Start", "End")]
        items.append((f"{curve} (location Z)", {n: specs[n].typical_lower for n in names},
                      {n: specs[n].typical_upper for n in names}))
    for key in layout["shape_keys"]:
        name = f"Shape_key_{key}"
        items.append((key, {name: specs[name].lower}, {name: specs[name].upper}))
    return items


def render_range_sheet(model: PinnaModel, path: str | os.PathLike, columns: int = 8,
                       panel_px: int = 300, max_colour_mm: float = 5.0) -> Path:
    """PNG sheet: every curve and shape key at the lower and upper limit of its range, lateral view,
    coloured by the displacement from the template (0 to `max_colour_mm`)."""
    pv = _pyvista()
    items = range_sheet_items()
    panels = [(f"{title}\n{side}", values) for title, low, high in items for side, values in (("min", low), ("max", high))]
    rows = int(np.ceil(len(panels) / columns))
    plotter = pv.Plotter(off_screen=True, shape=(rows, columns), window_size=(columns * panel_px, rows * panel_px),
                         border=False)
    rest = model.template_vertices_mm
    for index, (title, values) in enumerate(panels):
        plotter.subplot(index // columns, index % columns)
        vertices = model.evaluate(PinnaParameters.from_dict(values))
        mesh = _polydata(pv, vertices, model.faces)
        mesh["displacement_mm"] = np.linalg.norm(vertices - rest, axis=1)
        plotter.add_mesh(mesh, scalars="displacement_mm", clim=(0.0, max_colour_mm), cmap="viridis",
                         smooth_shading=True, show_scalar_bar=False)
        plotter.add_text(title, font_size=7)
        _lateral_camera(plotter, rest)
    model.set_parameters(PinnaParameters.default())
    path = Path(path)
    with atomic_path(path) as tmp:
        plotter.screenshot(str(tmp))
    plotter.close()
    return path


@dataclass(frozen=True)
class DistanceScale:
    """Colours of a distance map: ``low_mm``..``high_mm`` spread over the colour map ``cmap``, named ``label``."""
    low_mm: float
    high_mm: float
    cmap: str
    label: str


PAPER_SCALE = DistanceScale(1.0, 5.0, "jet_r", "paper's scale")
"""The paper's distance colours: <= 1 mm red, ~3.5 mm green, >= 5 mm blue."""
FINE_SCALE = DistanceScale(0.0, 1.5, "viridis", "0-1.5 mm")
"""For fits that lie within 1 mm nearly everywhere, where the paper's map is red all over."""


def render_distance_map(mesh_vertices_mm: np.ndarray, faces: np.ndarray | None, distance_mm: np.ndarray,
                        path: str | os.PathLike, title: str = "", size_px: tuple[int, int] = (1500, 750),
                        scale: DistanceScale = PAPER_SCALE) -> Path:
    """PNG of a pinna coloured by distance (mm) on ``scale`` (the paper's by default): lateral view (from +y)
    and a view from behind-above. `faces` None: points."""
    pv = _pyvista()
    if faces is None:
        data = pv.PolyData(np.asarray(mesh_vertices_mm, np.float64))
    else:
        data = _polydata(pv, mesh_vertices_mm, faces)
    data["distance_mm"] = np.asarray(distance_mm, dtype=np.float64)
    plotter = pv.Plotter(off_screen=True, shape=(1, 2), window_size=size_px)
    centre = np.asarray(mesh_vertices_mm).mean(axis=0)
    for column, eye in enumerate(([0.0, 1.0, 0.0], [-0.6, 0.6, 0.5])):
        plotter.subplot(0, column)
        plotter.add_mesh(data, scalars="distance_mm", cmap=scale.cmap, clim=(scale.low_mm, scale.high_mm),
                         smooth_shading=True,
                         point_size=4, render_points_as_spheres=faces is None,
                         scalar_bar_args={"title": "distance (mm)"} if column == 1 else None,
                         show_scalar_bar=column == 1)
        plotter.camera_position = [tuple(centre + 260.0 * np.array(eye)), tuple(centre), (0.0, 0.0, 1.0)]
        plotter.camera.parallel_projection = True
        plotter.camera.parallel_scale = 0.6 * np.ptp(np.asarray(mesh_vertices_mm)[:, 2])
        if column == 0 and title:
            plotter.add_text(title, font_size=11)
    path = Path(path)
    with atomic_path(path) as tmp:
        plotter.screenshot(str(tmp))
    plotter.close()
    return path
