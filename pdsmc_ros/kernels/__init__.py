"""The numba kernels' infrastructure: their compile options (options.py), numba's on-disk cache kept
consistent with their sources (cache.py) and filled at install time (precompile.py)."""
