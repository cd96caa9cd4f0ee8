"""Simulation: parametric cars, one airborne scanner (ray-cast passes with noise), car parks and non-cars, tiled
cities, the recognition accuracy against the truth, and the demo. Used by the tests, the benchmarks, the library
report and ``twinreg demo``/``simulate-city``; never by the per-scene pipeline."""
