"""Control laws by name: what a law declares, the gains validated against it, and the registry.

A law module builds a :class:`LawEntry` -- its name, its gains (:class:`GainSpec`: name,
shape, units, bounds, description, the scenario factor that scales it), its compiled form's
code or its torque written in Python, optionally its linear part for the discrete stability check --
and is an entry point of the group ``pdsmc_ros.laws`` (:mod:`pdsmc_ros.plugins`: the built-in
laws' in this package, a user's in a package of its own), or registers it in-process with
:func:`register_law`. Everything that handles gains reads these declarations, plugins' included:
the CLI's gain flags, the nodes' gain parameters and their descriptors, the params files of
``pdsmc tune`` and the reports (:func:`gain_specs`, :func:`law`); a run holds its law's gains as
:class:`Gains`, validated against the law's :class:`GainSpec` rows. A law's preset gains, if any,
live in ``config/gains.yaml``; a law written in Python runs behind
:mod:`pdsmc_ros.control.python_form`, in the same loop as the compiled ones.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..config import choice
from ..errors import ConfigError, InvalidInputError
from ..plugins import LAW_GROUP, PluginGroup, Registered
from ..robots.base import FloatArray, Manipulator

KP, KD, KS, LAM, PHI = range(5)
"""Rows of the thesis laws' gain matrix (:data:`pdsmc_ros.control.laws.THESIS_ROWS`)."""

SMC_MODEL_KEYS = ("mass", "coriolis", "gravity", "damping", "motor_inertia", "at_desired")
"""The SMC's model estimate, as entries of :attr:`LawSetup.smc_model` (``config/gains.yaml``)."""
S_MASS, S_CORIOLIS, S_GRAVITY, S_DAMPING, WITH_MOTOR_INERTIA, AT_DESIRED = range(6)


@dataclass(frozen=True)
class GainSpec:
    """One gain a law declares.

    Attributes
    ----------
    name : str
        The ROS parameter, the CLI flag (``--name``), the params-file key and the key of
        :class:`Gains`.
    description : str
        What it is (the parameter's descriptor, ``--help``).
    units : str
        Its units (e.g. ``N m/rad``).
    per_joint : bool
        One value per joint (a diagonal gain), or one scalar for every joint.
    lower : float
        Lowest allowed value (``>= lower``, or ``> lower`` when ``lower_open``).
    lower_open : bool
        The bound ``lower`` itself is refused (a boundary layer's ``phi > 0``).
    upper : float
        Highest allowed value (inclusive).
    neutral : float
        The value that leaves a law unchanged: fills a row of the gain matrix a law
        lays out but does not use (the thesis laws share one layout).
    scaled_by : str or None
        The key of a scenario's ``gain_factors`` (``config/scenarios.yaml``, Section 4.5.3)
        that multiplies it; None: its own name.
    start : float or None
        Where ``pdsmc tune`` starts it when the thesis's recipe (Section 4.2.3, which sets
        ``kp, kd, ks, lam, phi``) does not; None: :attr:`neutral`.
    """

    name: str
    description: str
    units: str
    per_joint: bool = True
    lower: float = 0.0
    lower_open: bool = False
    upper: float = math.inf
    neutral: float = 0.0
    scaled_by: str | None = None
    start: float | None = None

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise InvalidInputError(f"gain name {self.name!r} must be an identifier (a parameter and a flag)")

    @property
    def factor_key(self) -> str:
        """The scenario factor that scales it."""
        return self.scaled_by or self.name

    @property
    def bounds(self) -> str:
        """``>= 0``, ``> 0``, ``in [0, 10]`` ... (messages and descriptors)."""
        low = f"{'>' if self.lower_open else '>='} {self.lower:g}"
        if math.isinf(self.upper):
            return low
        return f"{low} and <= {self.upper:g}"

    def help(self) -> str:
        """One line for a descriptor or ``--help``."""
        shape = "one per joint" if self.per_joint else "one value for every joint"
        return f"{self.description} ({self.units}, {shape}, {self.bounds}; empty: the preset)"

    def check(self, values: FloatArray, controller: str) -> None:
        """Raise a ConfigError naming the gain if ``values`` break its bounds."""
        low_ok = values > self.lower if self.lower_open else values >= self.lower
        if not np.all(np.isfinite(values)) or not np.all(low_ok) or np.any(values > self.upper):
            raise ConfigError(f"gain {self.name} of {controller} must be finite and {self.bounds}, "
                              f"got {values.tolist()}")


@dataclass(frozen=True)
class Gains(Mapping[str, tuple[float, ...]]):
    """A law's gains by name, in the order of its gain matrix's rows (:attr:`LawEntry.rows`).

    A per-joint gain holds ``n`` values, a scalar one value. Read one as ``gains["kp"]``.

    Attributes
    ----------
    n : int
        Joints.
    rows : tuple of (str, tuple of float)
        Each row's gain name and values.
    """

    n: int
    rows: tuple[tuple[str, tuple[float, ...]], ...]

    def __getitem__(self, name: str) -> tuple[float, ...]:
        for key, values in self.rows:
            if key == name:
                return values
        raise KeyError(name)

    def __iter__(self) -> Iterator[str]:
        return (key for key, _ in self.rows)

    def __len__(self) -> int:
        return len(self.rows)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], n: int, controller: str, *, partial: bool = False) -> Gains:
        """Build from a ``{kp: [...], ...}`` mapping, validated against ``controller``'s declaration.

        Names must be rows of the law, every gain it needs must be given, a per-joint gain needs
        ``n`` values (one value stands for all), a scalar one value, each within its bounds.
        Rows not given hold their neutral value (``partial``: needed ones too, to check one layer
        of a run's gains on its own).
        """
        entry = law(controller)
        names = [spec.name for spec in entry.row_specs]
        unknown = set(data) - set(names)
        if unknown:
            raise ConfigError(f"unknown gain(s) {sorted(unknown)} for {controller}; allowed: {', '.join(names)}")
        missing = [] if partial else [g for g in entry.gain_names if g not in data]
        if missing:
            raise ConfigError(f"{controller} needs gains {', '.join(missing)}")
        rows = []
        for spec in entry.row_specs:
            size = n if spec.per_joint else 1
            raw = data.get(spec.name, [spec.neutral] * size)
            what = f"{n} values (one per joint)" if spec.per_joint else "one value (for every joint)"
            try:
                arr = np.asarray(raw, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                raise ConfigError(f"gain {spec.name} must be numbers, {what}, got {raw!r}") from None
            if arr.size == 1:
                arr = np.full(size, arr[0])
            if arr.size != size:
                raise ConfigError(f"gain {spec.name} needs {what}, got {arr.size}")
            spec.check(arr, controller)
            rows.append((spec.name, tuple(float(v) for v in arr)))
        return cls(n, tuple(rows))

    def scaled(self, factors: Mapping[str, float]) -> Gains:
        """Gains with some multiplied (Section 4.5.3): ``factors`` by gain name."""
        return Gains(self.n, tuple(
            (key, tuple(v * float(factors[key]) for v in values) if key in factors else values)
            for key, values in self.rows
        ))

    def replaced(self, changes: Mapping[str, Any], controller: str) -> Gains:
        """These gains with some given anew, validated as :meth:`from_mapping` validates."""
        return Gains.from_mapping({**self.as_dict(), **changes}, self.n, controller)

    def matrix(self) -> np.ndarray:
        """``(rows, n)`` array (:attr:`LawSetup.gains`); a scalar gain fills its row."""
        return np.array([np.broadcast_to(np.asarray(values, dtype=float), (self.n,)) for _, values in self.rows],
                        dtype=float)

    def as_dict(self) -> dict[str, list[float]]:
        return {key: list(values) for key, values in self.rows}


@dataclass(frozen=True)
class LawSetup:
    """What a law is given besides the state and the reference.

    Attributes
    ----------
    gains : ndarray, shape (rows, n)
        The law's gain matrix, one row per entry of :attr:`LawEntry.rows`.
    model : Manipulator
        The nominal robot known to the law (model-based laws).
    smc_model : ndarray, shape (6,)
        The model estimate's scales (:data:`SMC_MODEL_KEYS`).
    state : ndarray, shape (state_size, n)
        The law's internal state (:attr:`LawEntry.state_size` floats per joint: an integrator's),
        updated in place by each torque call; zeros for a fresh law.
    h : float
        The period (s) the state is integrated with (one torque call per period).
    """

    gains: FloatArray
    model: Manipulator
    smc_model: FloatArray
    state: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    h: float = 0.0


NumpyLaw = Callable[[LawSetup, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray], FloatArray]
"""``torque(setup, q, qd, q_ref, qd_ref, qdd_ref)`` for one state (shape ``(n,)``)."""

PresetDerivation = Callable[[Mapping[str, FloatArray], Manipulator, FloatArray], Mapping[str, FloatArray]]
"""``(source gains by name, nominal model, start configuration) -> this law's gains by name``: a law's
presets derived from another law's (:attr:`LawEntry.presets_from`)."""

LinearGains = Callable[[FloatArray, FloatArray, FloatArray], tuple[FloatArray, FloatArray]]
"""``(gains, smc_model, mass) -> (Kp_eff, Kd_eff)``: the law's linear part inside its boundary layer."""

ErrorMap = Callable[[FloatArray, FloatArray, FloatArray], tuple[FloatArray, FloatArray]]
"""``(gains, qd_ref, qdd_ref) -> (E, G)``, each of shape ``(n, n)``: a law feeding back, linearised at the
reference, the errors ``E e`` and ``E edot + G e`` in place of the time-domain ``e`` and ``edot`` (a
position domain law's), so its linear part is ``(Kp_eff E + Kd_eff G, Kd_eff E)``."""

_GAINS: dict[str, GainSpec] = {}
_LAWS: dict[str, LawEntry] = {}


def _resolve(gains: Sequence[GainSpec | str], law_name: str) -> tuple[GainSpec, ...]:
    out = []
    for g in gains:
        if isinstance(g, GainSpec):
            out.append(g)
            continue
        PLUGINS.load_builtins()
        if g not in _GAINS:
            PLUGINS.load_all()  # a gain another installed law declares
        if g not in _GAINS:
            raise InvalidInputError(f"control law {law_name!r}: gain {g!r} is declared by no registered law; "
                                    f"declare it (a GainSpec) or use one of: {', '.join(_GAINS)}")
        out.append(_GAINS[g])
    return tuple(out)


@dataclass(frozen=True)
class LawEntry:
    """A control law, declaring itself.

    Attributes
    ----------
    name : str
        Its name (``-p type:=``, ``--controller``, ``RunSpec.controller``).
    label : str
        How tables and figures print it.
    gains : tuple of GainSpec
        The gains it needs (a name string: a gain another registered law declares).
    torque : callable or None
        A law written in Python: its torque, :data:`NumpyLaw` (run behind
        :mod:`pdsmc_ros.control.python_form`); None for a law with a compiled form.
    equation : str
        Where it is written (thesis equation).
    code : int or None
        The code of its compiled form in :func:`pdsmc_ros.control.law.law_torque`
        (None: written in Python, ``torque``).
    linear_gains : callable or None
        Its linear part, for the discrete stability check
        (:mod:`pdsmc_ros.control.stability`); None: not checked.
    rows : tuple of GainSpec
        The rows of its gain matrix (:attr:`LawSetup.gains`), a superset of ``gains`` (rows it
        does not use hold :attr:`GainSpec.neutral` unless given); empty: ``gains``.
    model_based : bool
        It uses the nominal model's estimate (``--smc-reading``, ``smc_reading:=``).
    state_size : int
        Floats of internal state per joint (an integrator: :attr:`LawSetup.state`); 0: none.
        The state is integrated once per torque call with the control period ``h``.
    presets_from : str or None
        Without presets of its own in ``config/gains.yaml``, the law takes those of this law:
        the gains both declare as they are, the rest from ``derive_presets``.
    derive_presets : callable or None
        :data:`PresetDerivation`: its gains from ``presets_from``'s (and from the nominal model
        at the reference's start), for its presets and ``pdsmc tune``'s starting point.
    error_map : callable or None
        :data:`ErrorMap`: the errors it feeds back are ``E e`` and ``E edot + G e``, not the time-domain
        ``e`` and ``edot`` (the stability check maps its linear gains at each sampled reference velocity
        and acceleration); None: ``E = I``, ``G = 0``.
    """

    name: str
    label: str
    gains: tuple[GainSpec | str, ...]
    torque: NumpyLaw | None = None
    equation: str = ""
    code: int | None = None
    linear_gains: LinearGains | None = None
    rows: tuple[GainSpec | str, ...] = ()
    model_based: bool = False
    state_size: int = 0
    presets_from: str | None = None
    derive_presets: PresetDerivation | None = None
    error_map: ErrorMap | None = None

    def __post_init__(self) -> None:
        if self.state_size < 0:
            raise InvalidInputError(f"control law {self.name!r}: state_size must be >= 0, got {self.state_size}")
        if not self.name or not self.gains:
            raise InvalidInputError(f"control law {self.name!r}: needs a name and its gains, got {self.gains}")
        if (self.code is None) == (self.torque is None):
            raise InvalidInputError(f"control law {self.name!r}: give either its compiled form's code or its "
                                    "Python torque, not both and not neither")
        gains = _resolve(self.gains, self.name)
        rows = _resolve(self.rows, self.name) if self.rows else gains
        names = [r.name for r in rows]
        if len(set(names)) != len(names) or any(g not in rows for g in gains):
            raise InvalidInputError(f"control law {self.name!r}: rows {names} must name each gain once and "
                                    f"hold every gain it needs ({[g.name for g in gains]})")
        object.__setattr__(self, "gains", gains)
        object.__setattr__(self, "rows", rows)

    @property
    def specs(self) -> tuple[GainSpec, ...]:
        """:attr:`gains` as declarations (resolved at construction)."""
        return tuple(g for g in self.gains if isinstance(g, GainSpec))

    @property
    def gain_names(self) -> tuple[str, ...]:
        """Names of the gains it needs."""
        return tuple(g.name for g in self.specs)

    @property
    def row_specs(self) -> tuple[GainSpec, ...]:
        """:attr:`rows` as declarations."""
        return tuple(g for g in self.rows if isinstance(g, GainSpec))

    def presets_of(self, source: Mapping[str, Sequence[float] | float], model: Manipulator,
                   q0: FloatArray) -> dict[str, list[float]]:
        """Its gains from :attr:`presets_from`'s ``source``: the gains both declare as given,
        then :attr:`derive_presets`' (``model``: the nominal robot, ``q0``: the reference's start)."""
        names = {g.name for g in self.row_specs}
        out = {k: [float(x) for x in np.atleast_1d(v)] for k, v in source.items() if k in names}
        if self.derive_presets is not None:
            arrays = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in source.items()}
            derived = self.derive_presets(arrays, model, np.asarray(q0, dtype=float))
            out.update({k: [float(x) for x in np.atleast_1d(v)] for k, v in derived.items()})
        return out


def register_law(entry: LawEntry) -> LawEntry:
    """Register a control law under its name, and its gains (one spec per gain name), in-process
    (a law of an installed package is an entry point instead: :mod:`pdsmc_ros.plugins`)."""
    PLUGINS.load_builtins()
    return _register(entry)


def _register(entry: LawEntry) -> LawEntry:
    if entry.name in _LAWS and _LAWS[entry.name] is not entry:
        raise InvalidInputError(f"a control law named {entry.name!r} is already registered")
    for spec in entry.row_specs:
        known = _GAINS.get(spec.name)
        if known is not None and known != spec:
            raise InvalidInputError(f"control law {entry.name!r}: gain {spec.name!r} is declared otherwise by "
                                    "another law; give it another name or use the declared one")
    for spec in entry.row_specs:
        _GAINS.setdefault(spec.name, spec)
    _LAWS[entry.name] = entry
    return entry


def _register_entry_point(name: str, loaded: object) -> None:
    """What :data:`PLUGINS` registers: the :class:`LawEntry` an entry point names."""
    if not isinstance(loaded, LawEntry):
        raise TypeError(f"names a {type(loaded).__name__}, not a pdsmc_ros.control.LawEntry")
    if loaded.name != name:
        raise ValueError(f"names the law {loaded.name!r}: an entry point is named as its law")
    _register(loaded)


PLUGINS = PluginGroup(LAW_GROUP, _register_entry_point)
"""The entry points of ``pdsmc_ros.laws``: the built-in laws, then installed packages' laws."""

LAWS: Mapping[str, LawEntry] = Registered(_LAWS, PLUGINS.load_all)
"""Registered control laws by name: the built-in ones in their order, then those registered
in-process and installed packages' (read-only: :func:`register_law`, entry points)."""

GAINS: Mapping[str, GainSpec] = Registered(_GAINS, PLUGINS.load_all)
"""Every gain a registered law declares, by name, in registration order (one spec per name:
two laws with a ``kp`` share its meaning, its parameter and its flag); installed laws' included."""


def unregister_law(name: str) -> None:
    """Remove a registered law (a test's own law, for example), and the gains only it declared."""
    _LAWS.pop(name, None)
    used = {g.name for entry in _LAWS.values() for g in entry.row_specs}
    for gain in [g for g in _GAINS if g not in used]:
        del _GAINS[gain]


def law_names() -> tuple[str, ...]:
    """Names of the registered laws, installed packages' included."""
    return tuple(LAWS)


def gain_names() -> tuple[str, ...]:
    """Names of every gain a registered law declares (the nodes declare them all)."""
    return tuple(GAINS)


def gain_specs() -> dict[str, GainSpec]:
    """Every gain a registered law declares, by name, in order (installed packages' laws included):
    what a node declares a parameter for, with its :meth:`GainSpec.help` and bounds."""
    return dict(GAINS.items())


def law(name: str) -> LawEntry:
    """The registered law ``name``; an installed package's is loaded on first use.

    Raises
    ------
    ConfigError
        One line: no law of that name (listing the others), or the installed plugin of that name
        does not load (naming its distribution and entry point).
    """
    PLUGINS.load_builtins()
    if isinstance(name, str) and name not in _LAWS:
        PLUGINS.load(name)
    if isinstance(name, str) and name in _LAWS:
        return _LAWS[name]
    return _LAWS[choice(name, law_names(), "controller")]  # unknown: the error lists every law


def law_label(name: str) -> str:
    """How tables print the law ``name``."""
    return law(name).label


def smc_model_vector(smc_model: Mapping[str, float]) -> FloatArray:
    """:attr:`LawSetup.smc_model` from its mapping (every key of :data:`SMC_MODEL_KEYS`)."""
    return np.array([float(smc_model[k]) for k in SMC_MODEL_KEYS])
