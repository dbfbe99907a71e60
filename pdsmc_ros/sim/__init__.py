"""Simulation: the plant step (RK4, zero-order hold), the closed loop, whole runs."""

from ..metrics.statistics import build_samples
from .loop import closed_loop
from .plant import PlantStepper
from .rk4 import rk4_step_compiled
from .simulator import RunResult, simulate, simulate_many

__all__ = [
    "PlantStepper",
    "RunResult",
    "build_samples",
    "closed_loop",
    "rk4_step_compiled",
    "simulate",
    "simulate_many",
]
