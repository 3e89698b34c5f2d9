"""Signal primitives that both the HRTF I/O (:mod:`mesh2hrtf_io`) and the localisation model (:mod:`amt_bridge`)
build on: the ERB-number scale and minimum phase. NumPy only; imports nothing of the project."""
