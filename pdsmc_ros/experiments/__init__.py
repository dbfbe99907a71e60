"""Experiments over many runs: comparing control laws side by side (``pdsmc compare``).

Above the runs (:mod:`pdsmc_ros.presets`, :mod:`pdsmc_ros.sim`, :mod:`pdsmc_ros.experiments.montecarlo`)
and below the command line: nothing here imports :mod:`pdsmc_ros.cli` (``pdsmc compare`` is
:mod:`pdsmc_ros.cli.compare`).
"""
