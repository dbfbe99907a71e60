"""Control-parameter sweeps of Section 4.2.3 (Table 4.15, Figs. 4.29-4.36), for any law.

The thesis's sweep: one parameter of the PD-SMC law varies while the others stay at the
baseline (Kp = 5000, Kd = 1000, Ks = 5, lambda = 10, phi = 0.5 on every axis); each run's mean
contour error and error bounds are recorded. Increments follow the thesis: 1 up to 10, 10 up to
100, 100 up to 1000, 1000 up to 10000. Any other law sweeps any gain it declares the same way,
from its presets for the robot and contour, over the values given (``--values``: the thesis
gives no range for them).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..control.registry import Gains, law
from ..control.stability import rate_margin
from ..errors import InvalidInputError
from ..robots import make_robot
from ..runs.builder import RunSpec, make_run
from ..sim import simulate_many

BASELINE = {"kp": 5000.0, "kd": 1000.0, "ks": 5.0, "lam": 10.0, "phi": 0.5}
RANGES = {"kp": (10.0, 10000.0), "kd": (0.0, 10000.0), "ks": (1.0, 200.0), "lam": (0.0, 200.0)}


def thesis_values(lo: float, hi: float) -> list[float]:
    """Values from ``lo`` to ``hi`` with the thesis's decade-dependent increments."""
    values = []
    v = lo
    while v <= hi + 1e-9:
        values.append(round(v, 9))
        step = 1.0 if v < 10 else 10.0 if v < 100 else 100.0 if v < 1000 else 1000.0
        v += step
    return values


@dataclass(frozen=True)
class SweepPoint:
    value: float
    rate: float
    contour_mean: float
    contour_sd: float
    contour_max: float
    within_pct: float
    diverged: bool


THESIS_LAW = "pdsmc"
"""The law whose sweep the thesis runs (its baseline :data:`BASELINE`, its ranges :data:`RANGES`)."""


def sweep_params(controller: str = THESIS_LAW) -> tuple[str, ...]:
    """The gains ``--param`` may vary: every gain ``controller`` declares (those with a range in
    Table 4.15, :data:`RANGES`, for the thesis's PD-SMC, which sweeps them by default)."""
    names = law(controller).gain_names
    return tuple(name for name in names if name in RANGES) if controller == THESIS_LAW else names


def _baseline(controller: str, robot: str, contour: str, n: int) -> dict[str, list[float]]:
    """The gains that stay put: the thesis's baseline for its PD-SMC, the law's presets otherwise."""
    if controller == THESIS_LAW:
        return {k: [v] * n for k, v in BASELINE.items()}
    return {k: list(v) for k, v in make_run(robot, contour, controller).gains.items()}


def sweep_specs(
    param: str, robot: str, contour: str, values: list[float] | None = None, controller: str = THESIS_LAW
) -> tuple[str, list[RunSpec]]:
    """Runs of the sweep, each at a control rate where its gains are stable.

    The swept gain takes each value on every joint. ``values`` defaults to the thesis's values
    over the range of Table 4.15 (the PD-SMC's gains; another law's sweep needs them given).
    """
    swept = sweep_params(controller)
    if param not in swept:
        raise InvalidInputError(f"unknown sweep parameter {param!r} of {controller}; choose one of: {', '.join(swept)}")
    if values is None and controller != THESIS_LAW:
        raise InvalidInputError(f"the thesis gives no range for {controller}'s {param}: give the values to sweep "
                                "(--values, e.g. 1,10,100)")
    if values is not None and (not values or any(not np.isfinite(v) or v < 0 for v in values)):
        raise InvalidInputError(f"sweep values must be finite numbers >= 0, got {values}")
    n = make_robot(robot).n
    spec_of = law(controller).specs
    per_joint = {g.name: g.per_joint for g in spec_of}
    baseline = _baseline(controller, robot, contour, n)
    specs = []
    for value in values if values is not None else thesis_values(*RANGES[param]):
        gains = Gains.from_mapping({**baseline, param: [value] * n if per_joint[param] else value}, n, controller)
        spec = make_run(robot, contour, controller, gains=gains)
        check = rate_margin(spec, spec.reference(), points=7)
        if not check.stable:
            needed = 1.25 * check.lowest_stable_rate
            rate = math.ceil(needed / spec.sample_rate) * spec.sample_rate
            spec = dataclasses.replace(spec, rate=float(rate))
        specs.append(spec)
    return param, specs


def run_sweep(
    param: str,
    robot: str,
    contour: str,
    *,
    values: list[float] | None = None,
    workers: int | None = None,
    progress: Callable[[int, int, object], None] | None = None,
    scheduler: str | None = None,
    controller: str = THESIS_LAW,
) -> tuple[str, list[SweepPoint]]:
    param, specs = sweep_specs(param, robot, contour, values, controller)
    results = simulate_many(specs, workers=workers, progress=progress, scheduler=scheduler)
    points = []
    for spec, res in zip(specs, results, strict=True):
        eps = np.abs(res.samples.contour_error)
        diverged = not np.all(np.isfinite(eps)) or float(np.nanmax(eps)) > 0.05
        points.append(
            SweepPoint(
                value=float(spec.gains[param][0]),
                rate=spec.rate,
                contour_mean=res.metrics.contour_mean,
                contour_sd=res.metrics.contour_sd,
                contour_max=float(np.nanmax(eps)),
                within_pct=res.metrics.contour_within_pct,
                diverged=diverged,
            )
        )
    return param, points


