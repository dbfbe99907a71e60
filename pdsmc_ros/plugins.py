"""Laws and robots as plugins: Python entry points, the pluginlib of Python packaging.

A control law is an entry point of the group ``pdsmc_ros.laws`` naming a
:class:`~pdsmc_ros.control.LawEntry`; a robot one of ``pdsmc_ros.robots`` naming a
:class:`~pdsmc_ros.robots.Manipulator` subclass, a URDF arm or a
:class:`~pdsmc_ros.robots.RobotEntry` (a robot with its configuration). The entry point's name is
the law's or the robot's. A package of one's own declares them in its packaging
(``pyproject.toml``)::

    [project.entry-points."pdsmc_ros.laws"]
    pid = "my_laws.pid:PID"

and, once installed, its law runs wherever a built-in one does (``pdsmc simulate --controller pid``,
``ros2 run pdsmc_ros controller --ros-args -p type:=pid``), its gains declared as theirs are.

The built-in laws and robots are entry points of the same groups, declared once below
(:data:`BUILTIN_ENTRY_POINTS`: ``setup.py`` reads it into the package's metadata) and loaded by
the same code as a plugin's. The registries load them on first use
(:class:`PluginGroup`): the built-ins in their order, another package's entry points when a name
is not built in or when every law or robot is listed. A plugin that fails to load (its import,
the object it names, a name taken) is left out with one line naming its distribution and entry
point; the built-ins never depend on it. ``setup.py`` reads :data:`BUILTIN_ENTRY_POINTS` from this
file's text (a literal), without importing the package.
"""

from __future__ import annotations

import importlib.metadata
import logging
from collections.abc import Callable, Iterator, Mapping
from typing import TypeVar

from .errors import ConfigError

LAW_GROUP = "pdsmc_ros.laws"
"""The entry-point group of control laws."""
ROBOT_GROUP = "pdsmc_ros.robots"
"""The entry-point group of robots."""

BUILTIN_ENTRY_POINTS = {
    "pdsmc_ros.laws": [
        "pd = pdsmc_ros.control.laws:PD_LAW",
        "smc = pdsmc_ros.control.laws:SMC_LAW",
        "pdsmc = pdsmc_ros.control.laws:PDSMC_LAW",
        "pdg = pdsmc_ros.control.baselines:PDG_LAW",
        "ctc = pdsmc_ros.control.baselines:CTC_LAW",
        "sta = pdsmc_ros.control.sliding:STA_LAW",
        "ismc = pdsmc_ros.control.sliding:ISMC_LAW",
        "pd_pos = pdsmc_ros.control.position_domain:PD_POS_LAW",
        "pdsmc_pos = pdsmc_ros.control.position_domain:PDSMC_POS_LAW",
    ],
    "pdsmc_ros.robots": [
        "serial_3r = pdsmc_ros.robots.serial_3r:Serial3R",
        "parallel_5r = pdsmc_ros.robots.parallel_5r:Parallel5R",
    ],
}
"""The package's own entry points, in the order every listing shows them (the thesis's laws and
robots first). ``setup.py`` declares exactly these; the registries load them from here, so a
checkout run without installing, or with an older install's metadata, has the same built-ins."""

DISTRIBUTION = "pdsmc_ros"
"""This package's distribution: its entry points in the metadata are :data:`BUILTIN_ENTRY_POINTS`."""

LOG = logging.getLogger(__name__)

V = TypeVar("V")


def _distribution(point: importlib.metadata.EntryPoint) -> str:
    dist = point.dist
    return f"{dist.name} {dist.version}" if dist is not None else "an unknown distribution"


def _same_distribution(name: str) -> bool:
    return name.replace("-", "_").lower() == DISTRIBUTION


class PluginGroup:
    """One entry-point group: its built-in entry points and the installed packages' ones.

    Parameters
    ----------
    group : str
        The entry-point group (:data:`LAW_GROUP`, :data:`ROBOT_GROUP`).
    register : callable
        ``register(name, loaded)``: registers what entry point ``name`` names, or raises a
        ``ValueError`` or ``TypeError`` saying why it cannot (its message is put on the plugin's
        one line).
    """

    def __init__(self, group: str, register: Callable[[str, object], None]) -> None:
        if group not in BUILTIN_ENTRY_POINTS:
            raise ValueError(f"entry-point group must be one of {', '.join(BUILTIN_ENTRY_POINTS)}, got {group!r}")
        self.group = group
        self._register = register
        self._builtins_loading = False
        self._builtins_loaded = False
        self._all_loaded = False
        self._loaded: set[tuple[str, str]] = set()
        self.failures: dict[str, str] = {}
        """Why each plugin left out was left out, by entry-point name."""

    def builtin_points(self) -> list[importlib.metadata.EntryPoint]:
        """The package's own entry points of the group (:data:`BUILTIN_ENTRY_POINTS`), in order."""
        out = []
        for line in BUILTIN_ENTRY_POINTS[self.group]:
            name, _, value = (part.strip() for part in line.partition("="))
            out.append(importlib.metadata.EntryPoint(name=name, value=value, group=self.group))
        return out

    def plugin_points(self) -> list[importlib.metadata.EntryPoint]:
        """Installed packages' entry points of the group, by distribution then name (this package's
        own left out: they are :meth:`builtin_points`)."""
        found = [p for p in importlib.metadata.entry_points(group=self.group)
                 if p.dist is None or not _same_distribution(p.dist.name)]
        return sorted(found, key=lambda p: (_distribution(p), p.name))

    def load_builtins(self) -> None:
        """Register the built-in entry points (once; a broken built-in raises: it is a bug)."""
        if self._builtins_loaded or self._builtins_loading:
            return  # loading re-enters through the registry it fills
        self._builtins_loading = True
        try:
            for point in self.builtin_points():
                self._register(point.name, point.load())
            self._builtins_loaded = True
        finally:
            self._builtins_loading = False

    def load(self, name: str) -> None:
        """Register the installed plugins named ``name`` (after the built-ins).

        Raises
        ------
        ConfigError
            One of them cannot be loaded: the line naming its distribution, entry point and why.
        """
        self.load_builtins()
        for point in self.plugin_points():
            if point.name == name:
                failure = self._load_one(point)
                if failure:
                    raise ConfigError(failure)

    def load_all(self) -> None:
        """Register every installed plugin of the group (once); one that fails is left out with a
        warning line (:attr:`failures`)."""
        self.load_builtins()
        if self._all_loaded or self._builtins_loading:
            return
        self._all_loaded = True
        for point in self.plugin_points():
            failure = self._load_one(point)
            if failure:
                LOG.warning("%s (left out)", failure)

    def _load_one(self, point: importlib.metadata.EntryPoint) -> str:
        key = (_distribution(point), point.value)
        if key in self._loaded:
            return ""
        where = f"plugin {_distribution(point)}: entry point {self.group} '{point.name} = {point.value}'"
        try:
            loaded = point.load()
        # a plugin is another package's code: whatever its import raises must not stop the built-ins
        except Exception as exc:  # noqa: BLE001
            return self._fail(point.name, f"{where} does not load: {type(exc).__name__}: {exc}")
        try:
            self._register(point.name, loaded)
        except (TypeError, ValueError) as exc:
            return self._fail(point.name, f"{where}: {exc}")
        self._loaded.add(key)
        self.failures.pop(point.name, None)
        return ""

    def _fail(self, name: str, message: str) -> str:
        line = " ".join(message.split())  # one line, whatever the exception's text holds
        self.failures[name] = line
        return line


class Registered(Mapping[str, V]):
    """A registry's entries as a read-only mapping that loads its plugins on first use.

    Parameters
    ----------
    entries : dict
        The registry's own dictionary (registration order).
    load : callable
        Loads every entry point of the registry's group (:meth:`PluginGroup.load_all`).
    """

    def __init__(self, entries: dict[str, V], load: Callable[[], None]) -> None:
        self._entries = entries
        self._load = load

    def __getitem__(self, key: str) -> V:
        self._load()
        return self._entries[key]

    def __iter__(self) -> Iterator[str]:
        self._load()
        return iter(self._entries)

    def __len__(self) -> int:
        self._load()
        return len(self._entries)

    def __contains__(self, key: object) -> bool:
        self._load()
        return key in self._entries

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._entries!r})"
