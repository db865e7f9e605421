"""Small utilities every layer may use: atomic writes, the code version, worker pools, plots.

Nothing here imports another package of maniskill_tidy; it is the lowest layer.
"""
