"""Gains for a new arm by the thesis's recipe (Section 4.2.3), and the params file that carries them.

Section 4.2.3 tunes by sweeping Kp, Kd, Ks and lambda one at a time and keeping the
values that lower the contour error. :func:`tune` does that from a starting point
derived from the arm (:func:`starting_gains`), keeping only candidates that
``pdsmc check-gains`` accepts (:func:`~pdsmc_ros.control.stability.check_gains`: the
law's Eq. 3.19 conditions and the discrete rate condition with its margin, by default
for the real-time loop with its delay, the loop a robot runs) and that
do not exceed the arm's torque limits (URDF ``<limit effort>``); phi keeps its starting
value (the thesis's 0.25 rad/s, wider for a PD-SMC whose Ks must exceed gravity's torque).
Each candidate is one in-process run; with ``realism`` (``pdsmc tune --realism bench``) the check
also models the stand-in's command delay and velocity filter, and the run is against the MuJoCo
stand-in under those nuisances (:class:`Requirement`): only gains that hold on that arm are kept.
ROS-free.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..control.registry import Gains, law
from ..control.stability import THEOREM_LAWS, check_gains, loop_delay, plant_step
from ..errors import ConfigError, PdsmcError
from ..robots import make_robot
from ..robots.base import FloatArray
from ..robots.catalog import resolve_robot
from ..runs.builder import RunSpec, make_run

if TYPE_CHECKING:
    from ..sim.mujoco_lockstep import StandIn

SWEPT = ("kp", "kd", "ks", "lam", "omega_n", "k1", "k2")
"""The gains the recipe sweeps, in its order; then any other gain the law needs but :data:`KEPT`
(a law of another package: a PID's ``ki``)."""
KEPT = ("phi", "zeta")
"""The gains that keep their starting values (boundary layer, damping ratio)."""
FACTORS = (0.5, 0.7, 1.4, 2.0)
"""Multipliers tried on one swept gain (all joints at once) per round."""
BOUNDARY_LAYER = 0.25
"""phi of the starting point: the thesis's serial arm's (Table 4.16)."""
SLOWER_STARTS = 6
"""Times the starting bandwidth is halved when the starting gains fail the check."""
FOLLOWS = 0.5
"""The least share of the contour's extent the end effector must cover for a candidate to be kept.
The contour error is the distance to the nearest point of the path, so an arm that never leaves its
start (on the path) scores zero: held by the stand-in's Coulomb friction, a candidate with too little
torque did (``tune --realism bench``, SMC on the UR5: 1.5e-7 m, the end effector 0.12 m from its
desired point); a run that follows, however loosely, covers the extent."""


@dataclass(frozen=True)
class Requirement:
    """What every kept candidate passes: ``pdsmc check-gains --mode --delay-periods --margin
    [--realism]``; with ``realism`` (a preset of the stand-in) also a run against the MuJoCo stand-in
    under it that does not diverge, its torque within the limits."""

    mode: str = "realtime"
    delay_periods: int = 0
    margin: float | None = None  # None: the mode's (stability.REQUIRED_MARGIN)
    realism: str | None = None  # None: the in-process plant, no nuisance

    def __post_init__(self) -> None:
        loop_delay(self.mode, self.delay_periods)  # one line if either is wrong
        if self.margin is not None and (not np.isfinite(self.margin) or self.margin <= 0.0):
            raise ConfigError(f"margin must be a positive number, got {self.margin!r}")
        if self.realism is not None:
            from ..sim.realism import PRESETS

            if self.realism not in PRESETS:
                raise ConfigError(f"realism must be one of {', '.join(PRESETS)}, got {self.realism!r}")

    def stand_in(self) -> StandIn | None:
        """The stand-in every candidate runs against (None: the in-process plant)."""
        if self.realism is None:
            return None
        from ..sim.mujoco_lockstep import StandIn

        return StandIn(preset=self.realism)

    def loop_terms(self, robot: str, rate: float) -> tuple[int, FloatArray | None, FloatArray | None]:
        """The delay (periods, beyond the mode's), the velocity filter (Hz per joint, or None) and the
        viscous friction (N m s/rad per joint beyond the description's damping, or None: no damping) the
        check models for ``robot`` at ``rate``: ``delay_periods`` plus, with ``realism``, the stand-in's
        command delay, its velocity filter and its viscous friction
        (:meth:`pdsmc_ros.sim.realism.Realism.loop_terms`)."""
        stand_in = self.stand_in()
        if stand_in is None:
            return self.delay_periods, None, None
        _, realism, _ = stand_in.resolve(robot, rate)
        delay, filter_hz, viscous = realism.loop_terms()
        return self.delay_periods + delay, filter_hz, viscous

    def command(self) -> str:
        """The ``pdsmc check-gains`` that accepts the gains kept (a tuned params file's header)."""
        margin = "the mode's default margin" if self.margin is None else f"margin x{self.margin:g}"
        realism = "" if self.realism is None else f" --realism {self.realism}"
        return f"pdsmc check-gains --mode {self.mode} --delay-periods {self.delay_periods}{realism} ({margin})"


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

    @property
    def start(self) -> Candidate:
        """The starting point the search began from (the first candidate kept)."""
        return next(c for c in self.tried if c.ok)


def bandwidth(rate: float) -> float:
    """Closed-loop bandwidth (rad/s) of the starting point: a twentieth of the control rate,
    well inside the discrete stability region of a critically damped joint."""
    return rate / 20.0


def starting_gains(spec: RunSpec, w: float | None = None) -> Gains:
    """Critically damped joints at bandwidth ``w`` (:func:`bandwidth` by default), scaled by each
    joint's inertia, and for the PD-SMC inside the conditions of Eq. (3.19).

    With ``m_i`` the largest ``Mbar_ii`` along the reference (motor inertia included):
    ``Kp = m w^2``, ``Kd = 2 m w`` (Eq. 3.4 as a second-order joint); the SMC's sliding surface
    ``s = edot + lambda e`` (Eq. 3.13) with ``lambda = w / 2`` and, inside the boundary layer,
    ``Ks / phi = 2 m w`` (the same damping as the PD). The PD-SMC's theorem (Eq. 3.19) compares
    the smallest gain with the largest inertia: its ``Ks_i`` is raised above ``max |tau_d,i|``,
    ``Kd`` above ``lambda_M(K + C^T) / 2``, phi widened to keep ``Ks / phi <= Kd`` (the damping of
    the start), and lambda lowered until the rest hold. A law whose presets derive from another's
    (:attr:`LawEntry.derive_presets`) derives its start from these values (the computed torque:
    ``omega_n = sqrt(Kp / Mbar_ii)`` at the reference's start, ``zeta = 1``; the ISMC: the SMC's
    ``lambda`` lowered to keep the SMC's stiffness, :func:`~pdsmc_ros.control.sliding.ismc_presets`).
    """
    reference = spec.reference()
    t = np.linspace(0.0, reference.duration, 13)
    mass = spec.robot_model().mass_matrix(reference.sample(t).q)
    m = np.max(np.diagonal(mass, axis1=-2, axis2=-1), axis=0)
    w = bandwidth(spec.rate) if w is None else w
    values = {"kp": m * w * w, "kd": 2.0 * m * w, "ks": 2.0 * m * w * BOUNDARY_LAYER,
              "lam": np.full_like(m, w / 2.0), "phi": np.full_like(m, BOUNDARY_LAYER)}
    entry = law(spec.controller)
    if entry.derive_presets is not None:  # a law whose presets derive from another's: from this recipe's
        derived = entry.presets_of(dict(values), spec.nominal_model(), reference.sample([0.0]).q[0])
        values.update({k: np.asarray(v, dtype=float) for k, v in derived.items()})
    for g in entry.specs:  # a gain the recipe does not set starts where its law declares
        values.setdefault(g.name, np.full(len(m) if g.per_joint else 1, g.neutral if g.start is None else g.start))
    needed = entry.gain_names
    gains = _gains(values, needed, spec.controller)
    if spec.controller in THEOREM_LAWS:
        gains = _inside_theorem(spec, values, needed)
    return gains


def _gains(values: Mapping[str, np.ndarray], needed: Sequence[str], controller: str) -> Gains:
    n = len(values["kp"])
    return Gains.from_mapping({k: [float(x) for x in values[k]] for k in needed}, n, controller)


def _inside_theorem(spec: RunSpec, values: dict[str, np.ndarray], needed: Sequence[str]) -> Gains:
    """``values`` moved inside Eq. (3.19): Ks and Kd raised to the bounds that do not depend on
    the gains (``max |tau_d,i|``, ``lambda_M(K + C^T) / 2``), then lambda halved until all hold."""
    from ..control.lyapunov import theorem_conditions

    def conditions(v: Mapping[str, np.ndarray]) -> list:  # type: ignore[type-arg]
        return theorem_conditions(dataclasses.replace(spec, gains=_gains(v, needed, spec.controller)), points=101)

    first = conditions(values)
    tau_d = np.array([c.rhs for c in first if c.name.startswith("Ks_")])
    values["ks"] = np.maximum(values["ks"], 1.25 * tau_d)
    # a wider boundary layer keeps the damping Ks/phi of the start (a Ks above gravity's torque
    # over the thesis's 0.25 rad/s would be a damping no sampled loop holds)
    values["phi"] = np.maximum(values["phi"], values["ks"] / values["kd"])
    k_ct = next(c.rhs for c in first if c.name.startswith("lambda_m(Kd) > lambda_M"))
    values["kd"] = np.maximum(values["kd"], 1.25 * k_ct)
    for _ in range(30):
        if all(c.holds for c in conditions(values)):
            break
        values["lam"] = values["lam"] / 2.0
    return _gains(values, needed, spec.controller)


def evaluate(spec: RunSpec, gains: Gains, torque_limit: np.ndarray,
             requirement: Requirement | None = None, also: Sequence[RunSpec] = ()) -> Candidate:
    """One candidate: refused if ``check-gains`` refuses it (:class:`Requirement`) for ``spec``
    or any run of ``also`` (other contours the gains will serve), else one in-process run with
    ``gains``: its contour error, or why it is refused."""
    from ..sim import simulate  # numba: only when a run is made

    # without the clamp: a candidate that needs more than a joint's effort limit is refused below,
    # not run saturated (the clamp would hide what it needs)
    trial = dataclasses.replace(spec, gains=gains, enforce_limits=False)
    requirement = requirement or Requirement()
    try:
        delay, filter_hz, viscous = requirement.loop_terms(spec.robot, spec.rate)
        for run in (trial, *(dataclasses.replace(other, gains=gains) for other in also)):
            check = check_gains(run, mode=requirement.mode, delay_periods=delay, margin=requirement.margin,
                                filter_hz=filter_hz, friction_viscous=viscous)
            if not check.passes:
                where = "" if run is trial else f" on {run.contour}"
                return Candidate(gains, None, (), f"refused{where}: {check.failure()}")
        result = simulate(trial, stand_in=requirement.stand_in())
    except PdsmcError as exc:
        return Candidate(gains, None, (), f"refused: {exc}")
    metrics = result.metrics
    torque = tuple(float(x) for x in metrics.max_torque)
    if not np.isfinite(metrics.contour_mean):
        return Candidate(gains, None, torque, "diverged")
    covered = coverage(result.samples.xy, result.samples.xy_ref)
    if covered < FOLLOWS:
        return Candidate(gains, metrics.contour_mean, torque,
                         f"does not follow the contour: its end effector covered {covered:.0%} of the contour's "
                         f"extent (at least {FOLLOWS:.0%})")
    over = np.flatnonzero(np.asarray(torque) > torque_limit)
    if over.size:
        j = int(over[0])
        return Candidate(gains, metrics.contour_mean, torque,
                         f"joint {j + 1} needs {torque[j]:.4g} N m > its limit {torque_limit[j]:.4g}")
    return Candidate(gains, float(metrics.contour_mean), torque, "ok")


def coverage(xy: np.ndarray, xy_ref: np.ndarray) -> float:
    """The end effector's extent (the diagonal of the box its samples ``xy`` span) over the desired
    path's (``xy_ref``'s); 1 for a run without samples or a path of no extent."""
    extent = float(np.linalg.norm(np.ptp(xy_ref, axis=0))) if len(xy_ref) else 0.0
    if extent == 0.0:
        return 1.0
    return float(np.linalg.norm(np.ptp(xy, axis=0))) / extent


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
    requirement: Requirement | None = None,
    also: Sequence[str] = (),
    model: str | None = None,
) -> TuneResult:
    """Gains for ``robot`` on ``contour`` with ``controller`` by the recipe of Section 4.2.3.

    Parameters
    ----------
    robot, contour, controller : str
        As for :func:`~pdsmc_ros.runs.builder.make_run`.
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
    requirement : Requirement, optional
        The loop every candidate must be accepted for by ``check-gains`` (default: real time,
        :data:`~pdsmc_ros.control.stability.REALTIME_DELAY_PERIODS` of delay, margin x2: the loop on
        a robot, whose gains also run in lockstep).
        A starting point refused by it is retried at half the bandwidth, up to
        :data:`SLOWER_STARTS` times.
    also : sequence of str
        Other contours the gains will serve (a gain group of config/gains.yaml): every candidate
        must pass the check on them too.
    model : str, optional
        The arm model the law uses (:attr:`~pdsmc_ros.runs.builder.RunSpec.model`: an identified arm).

    Raises
    ------
    ConfigError
        If the plant cannot be integrated at this rate (a joint whose damping over inertia times
        the period is too large: the joint named, with the armature or rate that fixes it), or the
        starting point itself is refused (unstable at this rate, over a torque limit).
    """
    if rounds < 1:
        raise ConfigError(f"rounds must be >= 1, got {rounds!r}")
    if not factors or any(not np.isfinite(f) or f <= 0.0 for f in factors):
        raise ConfigError(f"factors must be positive numbers, got {list(factors)!r}")
    needed = law(controller).gain_names
    requirement = requirement or Requirement()
    spec = _spec(robot, contour, controller, rate, model)
    reference = spec.reference()
    step = plant_step(spec.robot_model(), reference.sample(np.linspace(0.0, reference.duration, 13)).q, spec.rate)
    if not step.holds:  # no gains can help: say which joint and what fixes it
        raise ConfigError(f"tune {robot}/{contour}/{controller} at {spec.rate:g} Hz: {step.problem()}")
    others = tuple(_spec(robot, name, controller, rate, model) for name in also)
    limit = _torque_limit(spec)
    tried: list[Candidate] = []
    w = bandwidth(spec.rate)
    for _ in range(SLOWER_STARTS + 1):
        best = evaluate(spec, start or starting_gains(spec, w), limit, requirement, others)
        tried.append(best)
        if progress:
            progress(best)
        if best.ok or start is not None or not best.verdict.startswith("refused"):
            break
        w /= 2.0
    if not best.ok:
        raise ConfigError(f"tune {robot}/{contour}/{controller}: the starting gains: {best.verdict}")
    swept = [name for name in SWEPT if name in needed] + [name for name in needed if name not in (*SWEPT, *KEPT)]
    with _evaluator(spec, limit, scheduler, requirement, others) as evaluate_all:
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
def _evaluator(spec: RunSpec, limit: np.ndarray, scheduler: str | None, requirement: Requirement,
               also: tuple[RunSpec, ...] = ()) -> Iterator[Callable[[list[Gains]], list[Candidate]]]:
    """Evaluate a batch of gains here, or as tasks on the Dask cluster of ``scheduler``."""
    if scheduler is None:
        yield lambda batch: [evaluate(spec, gains, limit, requirement, also) for gains in batch]
        return
    from ..sim.engine import dask_client, run_tasks

    with dask_client(scheduler) as client:
        def remote(batch: list[Gains]) -> list[Candidate]:
            out: list[Candidate | None] = [None] * len(batch)
            tasks = [(spec, gains, limit, requirement, also) for gains in batch]
            for i, candidate in run_tasks(client, evaluate, tasks):
                out[i] = candidate
            return out  # type: ignore[return-value]
        yield remote


def _spec(robot: str, contour: str, controller: str, rate: float | None, model: str | None = None) -> RunSpec:
    """The run to tune: the robot's settings with placeholder gains (replaced per candidate)."""
    needed = law(controller).gain_names
    n = make_robot(resolve_robot(robot)).n
    placeholder = Gains.from_mapping({k: [1.0] for k in needed}, n, controller)  # one value: every joint
    return make_run(robot, contour, controller, rate=rate, gains=placeholder, model=model)


def _torque_limit(spec: RunSpec) -> np.ndarray:
    """The arm's effort limits (inf where it has none): what a candidate may need at most."""
    limit = np.asarray(spec.robot_model().effort_limits, dtype=float)
    return np.where(limit > 0.0, limit, np.inf)
