"""Robots by name or path: the built-in ones, example-robot-data's arms, any URDF file.

:func:`resolve_robot` is what ``--robot`` / ``robot:=`` go through. A name of
``config/urdf_arms.yaml`` loads that arm from the example-robot-data wheel; a path
to a ``.urdf`` file loads it, with the options of a YAML file of the same name
beside it (``arm.urdf`` -> ``arm.yaml``: ``armature``, ``ee_frame``,
``locked_joints``, ``home``, ``plane``, ``orientation``, ``effort_limits``,
``velocity_limits``, ``position_limits``, the run settings of ``config/robots.yaml``
and ``contour_size``, ``contours``, ``gains``; each checked, one line naming the file
and the key). Either is registered once; a path is registered under its one spelling,
:func:`~.options.robot_key` (``arm.urdf``, ``./arm.urdf``, ``/home/me/arm.urdf`` and ``~/arm.urdf`` are one
robot), and the spelling it was asked by is kept as another name of the same arm.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..config import load_config, read_yaml
from ..errors import ConfigError, InvalidInputError
from .options import OPTION_KEYS, SETTING_KEYS, check_entry, robot_key
from .registry import find_robot, register_robot, robot_config, robot_names, unregister_robot
from .task import TaskPlane
from .urdf_robot import UrdfArm, urdf_arm

ROBOTS_DIR = "cmeel.prefix/share/example-robot-data/robots"
"""Where the example-robot-data wheel keeps its robots (relative to site-packages)."""

ROBOT_DESCRIPTION = "/robot_description"
"""The robot name that means: the arm of the URDF on ``/robot_description`` (its ``<pdsmc_ros>``
element, when a pdsmc_ros plant published it, carries the arm's task options and settings)."""

DEFAULT_SETTINGS = {"control_rate": 1000.0, "sample_rate": 500.0, "contour_bound": 1.0e-3, "contour_size": 0.3}
"""Run settings of a URDF arm that does not give its own."""



def catalog() -> Mapping[str, Any]:
    """The named URDF arms (``config/urdf_arms.yaml``)."""
    return load_config("urdf_arms")


def example_robot_data_dir() -> Path:
    """The example-robot-data wheel's ``robots`` directory.

    Raises
    ------
    ConfigError
        If the wheel is not installed.
    """
    try:
        found = Path(str(importlib.metadata.distribution("example-robot-data").locate_file(ROBOTS_DIR)))
    except importlib.metadata.PackageNotFoundError:
        found = None
    if found is None or not found.is_dir():
        raise ConfigError("the named URDF arms need the example-robot-data wheel: run make setup "
                          "(or pip install example-robot-data)")
    return found


def allowed_robots() -> str:
    """What ``--robot`` accepts, for error messages."""
    names = robot_names()
    return ", ".join([*names, *(n for n in catalog() if n not in names)]) + ", or a path to a .urdf file"


def resolve_robot(name: str) -> str:
    """Register the robot ``name`` names if it is not yet, and return its :func:`~.options.robot_key`.

    A ``.urdf`` path is registered under its key, and under ``name`` too (the same arm) so that
    either spelling builds it.

    Raises
    ------
    ConfigError
        One line naming ``name`` and what is allowed; or the URDF's problem.
    """
    if not isinstance(name, str) or not name:
        raise ConfigError(f"robot must be a name or a .urdf path, got {name!r}; allowed: {allowed_robots()}")
    key = robot_key(name)
    if find_robot(name) is not None and find_robot(key) is not None:  # built in, installed or registered already
        return key
    if name == ROBOT_DESCRIPTION:
        raise ConfigError(f"robot {name!r}: no URDF received on /robot_description yet (a node waits for it; "
                          "offline, the bag's /robot_description is used)")
    arms = catalog()
    if name in arms:
        entry = dict(arms[name])
        source = example_robot_data_dir() / str(entry.pop("urdf"))
        _register(name, source, entry, f"urdf_arms.yaml:{name}")
        return name
    if name.lower().endswith(".urdf"):  # a path: registered under its key
        path = Path(key)
        if find_robot(key) is None:
            if not path.is_file():
                where = "" if Path(name) == path else f" ({key})"
                raise ConfigError(f"robot {name!r}: no such URDF file{where}")
            options: dict[str, Any] = {}
            beside = path.with_suffix(".yaml")
            if beside.is_file():
                options = read_yaml(beside, str(beside)) or {}
                if not isinstance(options, dict):
                    raise ConfigError(f"{beside}: must be a mapping of options, got {type(options).__name__}")
            _register(key, path, options, str(beside))
        arm = find_robot(key)
        if name != key and find_robot(name) is None and isinstance(arm, UrdfArm):  # the spelling asked by, too
            register_robot(dataclasses.replace(arm, name=name), config=robot_config(key))
        return key
    raise ConfigError(f"unknown robot {name!r}; allowed: {allowed_robots()}")


def resolve_model(name: str) -> str:
    """A model of the arm (``--model``) registered like any robot (:func:`resolve_robot`); an options
    file ``arm.yaml`` names the URDF arm ``arm.urdf`` beside it (``pdsmc identify`` writes the pair).

    Raises
    ------
    ConfigError
        As :func:`resolve_robot`, or an options file without its URDF beside it.
    """
    if isinstance(name, str) and name.lower().endswith((".yaml", ".yml")):
        urdf = Path(name).with_suffix(".urdf")
        if not urdf.is_file():
            raise ConfigError(f"model {name!r}: no URDF {str(urdf)!r} beside the options file (an arm is X.urdf with "
                              "its options X.yaml)")
        return resolve_robot(str(urdf))
    return resolve_robot(name)


def register_description(xml: str, *, name: str = ROBOT_DESCRIPTION) -> str:
    """Register the arm of a ``/robot_description`` URDF under ``name`` (replacing an earlier one).

    Raises
    ------
    ConfigError
        One line: the URDF's problem, or a malformed ``<pdsmc_ros>`` element.
    """
    from xml.etree import ElementTree

    options: dict[str, Any] = {}
    try:
        root = ElementTree.fromstring(xml)
    except ElementTree.ParseError as exc:
        raise ConfigError(f"robot {name!r}: the URDF does not parse: {exc}") from None
    element = root.find("pdsmc_ros")
    if element is not None and (element.text or "").strip():
        try:
            options = json.loads(element.text or "")
        except json.JSONDecodeError as exc:
            raise ConfigError(f"robot {name!r}: its <pdsmc_ros> element is not JSON ({exc})") from None
        if not isinstance(options, dict):
            raise ConfigError(f"robot {name!r}: its <pdsmc_ros> element must hold a JSON object")
    unregister_robot(name)
    _register(name, xml, options, f"{name} <pdsmc_ros>")
    return name


def _register(name: str, source: Path | str, entry: Mapping[str, Any], where: str) -> UrdfArm:
    check_entry(entry, where)
    options = {k: entry[k] for k in OPTION_KEYS if k in entry and entry[k] is not None}
    if "plane" in options:
        try:
            options["plane"] = TaskPlane(**options["plane"])
        except (InvalidInputError, TypeError, ValueError) as exc:
            raise ConfigError(f"{where}: plane: {exc}") from None
    if "locked_joints" in options:
        options["locked_joints"] = tuple(options["locked_joints"])
    settings = {**DEFAULT_SETTINGS, **{k: entry[k] for k in SETTING_KEYS if k in entry}}
    try:
        arm = urdf_arm(source, name=name, settings=settings, options_label=where, **options)
    except InvalidInputError as exc:
        raise ConfigError(f"robot {name!r}: {exc}") from None
    register_robot(arm, config=settings)
    return arm
