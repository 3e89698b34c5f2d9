"""The project's imports have a direction: no cycle between modules, and each package imports only the packages
below it (pipeline.import_graph.LAYERS, drawn on docs/architecture.md)."""
from pathlib import Path

from pipeline.import_graph import LAYERS, cycles, module_graph, upward_imports

ROOT = Path(__file__).resolve().parents[1]


def test_no_import_cycle_between_modules():
    found = cycles(module_graph())
    assert not found, "import cycles (move what both sides need into the lower module): " + "; ".join(
        " <-> ".join(cycle) for cycle in found)


def test_packages_import_only_downwards():
    upward = upward_imports(module_graph())
    assert not upward, "imports against the layer order " + " < ".join(LAYERS) + ": " + "; ".join(upward)


def test_the_checker_finds_a_cycle(tmp_path):
    # two modules of a toy package that import each other, one of them inside a function
    package = tmp_path / "toy"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from .b import g\n\ndef f():\n    return g()\n")
    (package / "b.py").write_text("def g():\n    from toy.a import f\n    return f\n")
    (package / "c.py").write_text("import toy.a\n")
    assert cycles(module_graph(tmp_path, ("toy",))) == [["toy.a", "toy.b"]]


def test_every_package_is_in_a_layer():
    packages = {p.name for p in ROOT.iterdir() if (p / "__init__.py").is_file()}
    assert packages == set(LAYERS), f"add {sorted(packages - set(LAYERS))} to pipeline.import_graph.LAYERS"


def test_the_io_layer_does_not_stand_on_the_pinna_model():
    """mesh2hrtf_io and amt_bridge (and hrtf_dsp) import the shared helpers from core, nothing of ppm."""
    graph = module_graph()
    on_ppm = sorted(f"{module} -> {target}" for module, targets in graph.items()
                    if module.split(".")[0] in ("mesh2hrtf_io", "amt_bridge", "hrtf_dsp")
                    for target in targets if target.split(".")[0] == "ppm")
    assert not on_ppm, "; ".join(on_ppm)
    assert not any(graph[module] for module in graph if module.split(".")[0] == "core")
