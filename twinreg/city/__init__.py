"""City scale: a tiled, out-of-core build-twin on Dask (grid, sources, cells, engine, resume) and the simulated
city the tests and benchmarks use. The per-scene pipeline runs unchanged inside each cell."""
