"""The thesis's reproduction: its matrix as cells with their readings and verdicts, the runs
(in-process or over the nodes) and the report (``pdsmc reproduce``)."""

from .cells import Cell, Reproduction, compare, matrix_specs, run_key, summarize
from .report import write_report
from .reproduce import run_reproduction
from .verdicts import Verdict, classify, count_verdicts

__all__ = [
    "Cell",
    "Reproduction",
    "Verdict",
    "classify",
    "compare",
    "count_verdicts",
    "matrix_specs",
    "run_key",
    "run_reproduction",
    "summarize",
    "write_report",
]
