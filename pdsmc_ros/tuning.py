"""Gains for a new arm by the thesis's recipe (Section 4.2.3), and the params file that carries them.

Section 4.2.3 tunes by sweeping Kp, Kd, Ks and lambda one at a time and keeping the
values that lower the contour error. :func:`tune` does that from a starting point
derived from the arm (:func:`starting_gains`), inside the stable region (every
candidate passes :func:`~pdsmc_ros.control.stability.check_rate` at the run's rate)
and without exceeding the arm's torque limits (URDF ``<limit effort>``); phi stays
the thesis's 0.25 rad/s of boundary layer. Each candidate is one in-process run.
ROS-free.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .config import read_yaml
from .control.gains import Gains
from .control.registry import GAIN_NAMES, law
from .errors import ConfigError, PdsmcError
from .presets import RunSpec, make_run
from .robots import ROBOTS
from .robots.catalog import resolve_robot

SWEPT = ("kp", "kd", "ks", "lam")
"""The gains the recipe sweeps, in its order (phi keeps its starting value)."""
FACTORS = (0.5, 0.7, 1.4, 2.0)
"""Multipliers tried on one swept gain (all joints at once) per round."""
BOUNDARY_LAYER = 0.25
"""phi of the starting point: the thesis's serial arm's (Table 4.16)."""
NODE_NAME = "controller"
"""The node a params file written by :func:`write_params_file` configures."""


@dataclass(frozen=True)
class Candidate:
    """One evaluated set of gains."""

    gains: Gains
    contour_mean: float | None
    max_torque: tuple[float, ...]
    verdict: str  # "ok", or why it was refused

    @property
    def ok(self) -> bool:
        return self.verdict == "ok"


@dataclass(frozen=True)
class TuneResult:
    """The gains kept and every candidate tried, in order."""

    spec: RunSpec
    best: Candidate
    tried: tuple[Candidate, ...]


def bandwidth(rate: float) -> float:
    """Closed-loop bandwidth (rad/s) of the starting point: a twentieth of the control rate,
    well inside the discrete stability region of a critically damped joint."""
    return rate / 20.0


def starting_gains(spec: RunSpec) -> Gains:
    """Critically damped joints at :func:`bandwidth`, scaled by each joint's inertia.

    With ``m_i`` the largest ``Mbar_ii`` along the reference (motor inertia included) and
    ``w`` the bandwidth: ``Kp = m w^2``, ``Kd = 2 m w`` (Eq. 3.4 as a second-order joint);
    the SMC's sliding surface ``s = edot + lambda e`` (Eq. 3.13) with ``lambda = w / 2`` and,
    inside the boundary layer, ``Ks / phi = 2 m w`` (the same damping as the PD).
    """
    reference = spec.reference()
    t = np.linspace(0.0, reference.duration, 13)
    mass = spec.robot_model().mass_matrix(reference.sample(t).q)
    m = np.max(np.diagonal(mass, axis1=-2, axis2=-1), axis=0)
    w = bandwidth(spec.rate)
    values = {"kp": m * w * w, "kd": 2.0 * m * w, "ks": 2.0 * m * w * BOUNDARY_LAYER,
              "lam": np.full_like(m, w / 2.0), "phi": np.full_like(m, BOUNDARY_LAYER)}
    needed = law(spec.controller).gains
    return Gains.from_mapping({k: [float(x) for x in values[k]] for k in needed}, len(m), spec.controller)


def evaluate(spec: RunSpec, gains: Gains, torque_limit: np.ndarray) -> Candidate:
    """One in-process run with ``gains``: its contour error, or why it is refused."""
    from .sim import simulate  # numba: only when a run is made

    trial = dataclasses.replace(spec, gains=gains)
    try:
        result = simulate(trial)
    except PdsmcError as exc:
        return Candidate(gains, None, (), f"refused: {exc}")
    metrics = result.metrics
    torque = tuple(float(x) for x in metrics.max_torque)
    if not np.isfinite(metrics.contour_mean):
        return Candidate(gains, None, torque, "diverged")
    over = np.flatnonzero(np.asarray(torque) > torque_limit)
    if over.size:
        j = int(over[0])
        return Candidate(gains, metrics.contour_mean, torque,
                         f"joint {j + 1} needs {torque[j]:.4g} N m > its limit {torque_limit[j]:.4g}")
    return Candidate(gains, float(metrics.contour_mean), torque, "ok")


def tune(
    robot: str,
    contour: str,
    controller: str,
    *,
    rate: float | None = None,
    rounds: int = 6,
    factors: Sequence[float] = FACTORS,
    start: Gains | None = None,
    progress: Callable[[Candidate], None] | None = None,
    scheduler: str | None = None,
) -> TuneResult:
    """Gains for ``robot`` on ``contour`` with ``controller`` by the recipe of Section 4.2.3.

    Parameters
    ----------
    robot, contour, controller : str
        As for :func:`~pdsmc_ros.presets.make_run`.
    rate : float, optional
        Control rate (Hz); the robot's default otherwise.
    rounds : int
        Sweeps over :data:`SWEPT`; stops early when a round keeps nothing.
    factors : sequence of float
        Multipliers tried on each swept gain.
    start : Gains, optional
        Starting point; :func:`starting_gains` by default.
    progress : callable, optional
        Called with every evaluated candidate.
    scheduler : str, optional
        A Dask scheduler (``tcp://HOST:PORT``): each gain's candidates run there in parallel.
        The result does not depend on it: every candidate of a gain starts from the same best.

    Raises
    ------
    ConfigError
        If the starting point itself is refused (unstable at this rate, over a torque limit).
    """
    if rounds < 1:
        raise ConfigError(f"rounds must be >= 1, got {rounds!r}")
    if not factors or any(not np.isfinite(f) or f <= 0.0 for f in factors):
        raise ConfigError(f"factors must be positive numbers, got {list(factors)!r}")
    needed = law(controller).gains
    spec = _spec(robot, contour, controller, rate)
    limit = _torque_limit(spec)
    best = evaluate(spec, start or starting_gains(spec), limit)
    tried = [best]
    if progress:
        progress(best)
    if not best.ok:
        raise ConfigError(f"tune {robot}/{contour}/{controller}: the starting gains are {best.verdict}")
    swept = [name for name in SWEPT if name in needed]
    with _evaluator(spec, limit, scheduler) as evaluate_all:
        for _ in range(rounds):
            kept = False
            for name in swept:
                # one gain's factors together (in parallel on a cluster), all from the same best
                candidates = evaluate_all([best.gains.scaled({name: factor}) for factor in factors])
                tried += candidates
                for candidate in candidates:
                    if progress:
                        progress(candidate)
                better = [c for c in candidates if c.ok and c.contour_mean < best.contour_mean]  # type: ignore[operator]
                if better:
                    best, kept = min(better, key=lambda c: c.contour_mean), True  # type: ignore[arg-type,return-value]
            if not kept:
                break
    return TuneResult(dataclasses.replace(spec, gains=best.gains), best, tuple(tried))


@contextlib.contextmanager
def _evaluator(spec: RunSpec, limit: np.ndarray, scheduler: str | None
               ) -> Iterator[Callable[[list[Gains]], list[Candidate]]]:
    """Evaluate a batch of gains here, or as tasks on the Dask cluster of ``scheduler``."""
    if scheduler is None:
        yield lambda batch: [evaluate(spec, gains, limit) for gains in batch]
        return
    from .engine import dask_client, run_tasks

    with dask_client(scheduler) as client:
        def remote(batch: list[Gains]) -> list[Candidate]:
            out: list[Candidate | None] = [None] * len(batch)
            for i, candidate in run_tasks(client, evaluate, [(spec, gains, limit) for gains in batch]):
                out[i] = candidate
            return out  # type: ignore[return-value]
        yield remote


def _spec(robot: str, contour: str, controller: str, rate: float | None) -> RunSpec:
    """The run to tune: the robot's settings with placeholder gains (replaced per candidate)."""
    needed = law(controller).gains
    n = ROBOTS[resolve_robot(robot)].n
    placeholder = Gains.from_mapping({k: [1.0] * n for k in needed}, n, controller)
    return make_run(robot, contour, controller, rate=rate, gains=placeholder)


def _torque_limit(spec: RunSpec) -> np.ndarray:
    limit = getattr(spec.robot_model(), "torque_limit", None)
    n = len(spec.gains.kp)
    if limit is None:
        return np.full(n, np.inf)
    limit = np.asarray(limit, dtype=float)
    return np.where(limit > 0.0, limit, np.inf)


def write_params_file(path: str | Path, gains: Gains, *, controller: str, robot: str, contour: str,
                      rate: float, node: str = NODE_NAME) -> None:
    """A ROS 2 params file for the controller node (``--ros-args --params-file``)."""
    params: dict[str, Any] = {"robot": robot, "contour": contour, "type": controller, "rate": float(rate)}
    params.update({k: [float(x) for x in v] for k, v in gains.as_dict().items() if k in law(controller).gains})
    Path(path).write_text(yaml.safe_dump({node: {"ros__parameters": params}}, sort_keys=False))


def read_params_file(path: str | Path, n: int, controller: str, *, node: str = NODE_NAME) -> Gains:
    """The gains of a params file (as :func:`write_params_file` writes, or any with the gain names).

    Raises
    ------
    ConfigError
        One line naming the file and what is wrong.
    """
    data = read_yaml(path, f"params file {str(path)!r}")
    block = data.get(node, data.get("/**")) if isinstance(data, Mapping) else None
    params = block.get("ros__parameters") if isinstance(block, Mapping) else None
    if not isinstance(params, Mapping):
        raise ConfigError(f"params file {str(path)!r}: no {node}.ros__parameters mapping")
    values = {k: params[k] for k in GAIN_NAMES if k in params and params[k]}
    return Gains.from_mapping(values, n, controller)
