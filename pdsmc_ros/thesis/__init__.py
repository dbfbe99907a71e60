"""The thesis's experiments: the reproduction matrix and its report, gain sweeps, bag analysis
and figures (``pdsmc reproduce``, ``pdsmc sweep``, ``pdsmc analyze``)."""

from .analysis import analyze_bag, comparison_table, find_bags, write_outputs
from .cells import Cell, Reproduction, compare, matrix_specs, run_key, summarize
from .report import write_report
from .reproduce import run_reproduction
from .sweep import run_sweep, sweep_specs
from .verdicts import Verdict, classify, count_verdicts

__all__ = [
    "Cell",
    "Reproduction",
    "Verdict",
    "analyze_bag",
    "classify",
    "compare",
    "comparison_table",
    "count_verdicts",
    "find_bags",
    "matrix_specs",
    "run_key",
    "run_reproduction",
    "run_sweep",
    "summarize",
    "sweep_specs",
    "write_outputs",
    "write_report",
]
