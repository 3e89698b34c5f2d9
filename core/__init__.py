"""The project's base: helpers every stage shares, below every other package (pipeline/import_graph.py): atomic file
writes (:mod:`core.atomic`), progress lines for long stages (:mod:`core.progress`), where a mesh crosses itself
(:mod:`core.self_intersections`) and the error every domain error derives from (:mod:`core.errors`). It imports
nothing of the project."""
