"""Experiments over many runs: the thesis's reproduction (:mod:`.thesis`, ``pdsmc reproduce``),
gain sweeps (:mod:`.sweep`), tuning (:mod:`.tuning`), the Monte Carlo (:mod:`.montecarlo`),
comparing laws side by side (:mod:`.compare`, ``pdsmc compare``), bag analysis
(:mod:`.analysis`, ``pdsmc analyze``) and the figures (:mod:`.plots`).

Above the runs (:mod:`pdsmc_ros.runs.builder`, :mod:`pdsmc_ros.sim`) and below the command line:
nothing here imports :mod:`pdsmc_ros.cli`. The subpackages and modules are imported where used
(matplotlib and Dask load only for the commands that need them).
"""
