"""ROS 2 params files, read and written, and parameter names checked against what a node declares
(ROS-free): the one module that reads or writes a params file (``pdsmc tune`` writes one; ``pdsmc
simulate/check-gains/compare/montecarlo --params-file`` read the controller's gains from one; the
nodes check every file they are given against what they declare, :mod:`.overrides`).

A params file (``--ros-args --params-file``, ``pdsmc ... --params-file``) maps node names to
``ros__parameters``. rcl applies every section whose name matches the node -- its name,
its fully qualified name, or a wildcard pattern (``/**``, ``/*/controller``) -- and silently
ignores the rest, and a key no node declares is silently dropped. Here both are errors:
a file with no section for the node, or with a key the node does not declare (naming the
closest declared one), is one line naming the file.
"""

from __future__ import annotations

import contextlib
import difflib
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from ..config import read_yaml
from ..control.registry import Gains, gain_names, law
from ..errors import ConfigError
from ..robots.options import robot_key
from .declaration import JOINT, check_values, joint_name_matches
from .tables import NODES, gain_parameters, package_parameter_names, parameter_names
from .tables import node_parameters as node_table

ALWAYS_DECLARED = ("use_sim_time", "start_type_description_service")
"""Parameters rclpy declares on every node itself."""
ALWAYS_ALLOWED_PREFIXES = ("qos_overrides.",)
"""Parameters rclpy reads without declaring them for the node (QoS overrides of its topics)."""

NODE_NAMES = NODES
"""The package's nodes: one params file may configure several of them (``run_experiment.sh``
hands the same file to each)."""


def controller_parameters() -> tuple[str, ...]:
    """What the controller node declares, from its table (:func:`pdsmc_ros.parameters.node_parameters`),
    the gains of every registered law included: the keys ``pdsmc simulate/check-gains --params-file``
    accept (the CLI reads the controller's sections without starting ROS)."""
    return parameter_names("controller")


def __getattr__(name: str) -> object:
    # derived from the tables when asked, so the laws and robots registered by then are included
    if name == "CONTROLLER_PARAMETERS":  # the controller's own and the run's, without the gains
        gains = {spec.name for spec in gain_parameters(applied=True)}
        return tuple(n for n in parameter_names("controller") if n not in gains)
    if name == "PACKAGE_PARAMETERS":  # every parameter some node of the package declares
        return package_parameter_names()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def closest(name: str, names: Iterable[str]) -> str:
    """`` (did you mean 'type'?)`` for the declared name closest to ``name``, or ``''``."""
    match = difflib.get_close_matches(name, list(names), n=1, cutoff=0.6)
    return f" (did you mean {match[0]!r}?)" if match else ""


def unknown_parameter(name: str, declared: Iterable[str]) -> str:
    """``unknown parameter 'typ' (did you mean 'type'?)``."""
    return f"unknown parameter {name!r}{closest(name, declared)}"


def is_declared(name: str, declared: Iterable[str]) -> bool:
    """``name`` is declared, or one rclpy handles for every node."""
    declared = list(declared)
    return name in declared or name in ALWAYS_DECLARED or name.startswith(ALWAYS_ALLOWED_PREFIXES) or any(
        joint_name_matches(d, name) for d in declared if JOINT in d)  # constraints.<joint>.goal


def section_pattern(section: str) -> re.Pattern[str]:
    """rcl's node-name pattern of a section: ``*`` one name token, ``**`` any number of them;
    a name without a leading ``/`` is relative to the root namespace."""
    name = section if section.startswith("/") else "/" + section
    parts = re.split(r"(\*\*|\*)", name)
    regex = "".join(".*" if p == "**" else "[^/]*" if p == "*" else re.escape(p) for p in parts)
    return re.compile(regex)


def section_matches(section: str, node_fqn: str) -> bool:
    """Whether rcl applies ``section`` of a params file to the node ``node_fqn`` (``/ns/name``)."""
    return section_pattern(section).fullmatch(node_fqn) is not None


def _flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested mappings as rcl reads them: ``{a: {b: 1}}`` is the parameter ``a.b``."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(_flatten(value, name + "."))
        else:
            out[name] = value
    return out


def read_params_file(path: str | Path) -> dict[str, dict[str, Any]]:
    """The sections of a params file: ``{section: {parameter: value}}`` (nested names flattened).

    Raises
    ------
    ConfigError
        One line naming the file if it is not a mapping of sections each holding a
        ``ros__parameters`` mapping.
    """
    label = f"params file {str(path)!r}"
    data = read_yaml(path, label)
    if not isinstance(data, Mapping) or not data:
        raise ConfigError(f"{label}: expected node sections, e.g. 'controller: {{ros__parameters: {{kp: [...]}}}}' "
                          "or '/**: {ros__parameters: {...}}'")
    sections: dict[str, dict[str, Any]] = {}
    for section, block in data.items():
        params = block.get("ros__parameters") if isinstance(block, Mapping) else None
        if not isinstance(params, Mapping):
            raise ConfigError(f"{label}: section {section!r} has no ros__parameters mapping")
        extra = [k for k in block if k != "ros__parameters"]
        if extra:
            raise ConfigError(f"{label}: section {section!r}: unknown key {extra[0]!r} beside ros__parameters")
        sections[str(section)] = _flatten(params)
    return sections


def node_parameters(path: str | Path, node_fqn: str, declared: Iterable[str], *,
                    sections: Mapping[str, Mapping[str, Any]] | None = None) -> dict[str, Any]:
    """The parameters a params file gives the node ``node_fqn``, as rcl merges them (later
    sections override earlier ones), checked against the names the node ``declared``.

    Raises
    ------
    ConfigError
        If no section applies to the node, or a section that does holds a key the node does not
        declare (the closest declared name suggested).
    """
    label = f"params file {str(path)!r}"
    sections = read_params_file(path) if sections is None else sections
    declared = list(declared)
    matching = [name for name in sections if section_matches(name, node_fqn)]
    if not matching:
        # a file for other nodes of the run (the plant's and the controller's sections only) is fine;
        # one that configures no node of the package is a mistake (a misspelt section name)
        if any(section_matches(name, f"/{node}") for name in sections for node in NODE_NAMES):
            return {}
        name = node_fqn.rsplit("/", 1)[-1]
        raise ConfigError(f"{label}: no section for node {node_fqn!r} or any node of the package (sections: "
                          f"{', '.join(map(repr, sections))}; use '{name}:' or '/**:' for every node)")
    merged: dict[str, Any] = {}
    for section in matching:
        shared = "*" in section  # a pattern: it configures other nodes too
        for key, value in sections[section].items():
            if not is_declared(key, declared):
                if shared and key in package_parameter_names():
                    continue  # another node's parameter (e.g. the controller's enforce_limits in /**)
                raise ConfigError(f"{label}: section {section!r}: {unknown_parameter(key, declared)} for node "
                                  f"{node_fqn!r}")
            merged[key] = value
    name = node_fqn.rsplit("/", 1)[-1]
    if name in NODES:  # the values, as the node checks them when it starts
        try:
            check_values(node_table(name), merged, types_only=[g.name for g in gain_parameters(applied=True)])
        except ConfigError as exc:
            raise ConfigError(f"{label}: {exc}") from None
    return merged


def given_value(name: str, node_fqn: str, args: Iterable[str]) -> Any:
    """The value ``args`` give parameter ``name`` of node ``node_fqn`` before any node exists, as
    rcl resolves it: the params files in order, then ``-p`` (``name:=`` or ``node:name:=``), the
    last one winning; None if none does or a file cannot be read (the node's own start says why)."""
    args = list(args)
    value = None
    with contextlib.suppress(ConfigError):
        for path in params_files_in(args):
            for section, values in read_params_file(path).items():
                if name in values and section_matches(section, node_fqn):
                    value = values[name]
    node = node_fqn.rsplit("/", 1)[-1]
    for target, key, text in param_arguments(args):
        if key == name and target in ("", node):
            value = text
    return value


def params_files_in(args: Iterable[str]) -> list[str]:
    """The files of every ``--params-file FILE`` among a process's ROS arguments."""
    args = list(args)
    return [args[i + 1] for i, arg in enumerate(args[:-1]) if arg == "--params-file"]


def param_arguments(args: Iterable[str]) -> list[tuple[str, str, str]]:
    """Every ``-p``/``--param`` among a process's ROS arguments as ``(node, name, value)``: ``node``
    is "" for ``name:=value`` (every node) and the node's name for ``node:name:=value``."""
    args = list(args)
    found = []
    for flag, given in zip(args, args[1:]):
        if flag in ("-p", "--param") and ":=" in given:
            key, value = given.split(":=", 1)
            node, _, name = key.rpartition(":")
            found.append((node, name, value))
    return found


CONTROLLER_NODE = "controller"
"""The node whose section of a params file holds the gains (:func:`write_params_file`)."""


def controller_values(path: str | Path, *, node: str = CONTROLLER_NODE) -> dict[str, Any]:
    """What a params file gives the controller node (its section and ``/**``, merged as rcl does),
    checked against what the controller declares (:func:`controller_parameters`).

    Raises
    ------
    ConfigError
        One line naming the file: not a params file, no section for the controller, or a key the
        controller does not declare (the closest one suggested).
    """
    return node_parameters(path, "/" + node, controller_parameters())


def read_gains(path: str | Path, n: int, controller: str, *, node: str = CONTROLLER_NODE) -> dict[str, list[float]]:
    """The gains a params file gives ``controller`` (as :func:`write_params_file` writes, or any with the
    gain names): checked against the law's declaration, the others left to the presets (the
    params-file layer of :func:`~pdsmc_ros.runs.builder.make_run`).

    Raises
    ------
    ConfigError
        One line naming the file and what is wrong.
    """
    params = controller_values(path, node=node)
    values = {k: params[k] for k in gain_names() if k in params and params[k]}
    try:
        checked = Gains.from_mapping(values, n, controller, partial=True)
    except ConfigError as exc:
        raise ConfigError(f"params file {str(path)!r}: {exc}") from None
    return {k: list(checked[k]) for k in values}


def write_params_file(path: str | Path, gains: Gains, *, controller: str, robot: str, contour: str,
                      rate: float, node: str = CONTROLLER_NODE, accepted_by: str = "") -> None:
    """A ROS 2 params file for every node of a run (``--ros-args --params-file``).

    The run (robot, contour, type, rate) in ``/**``, which every node reads, and the gains in the
    controller's section, the only node that needs them: the same file serves ``ros2 run`` of
    any node, ``scripts/run_experiment.sh --params-file`` and ``pdsmc simulate --params-file``.
    ``accepted_by``: the check the gains passed, in the header (``pdsmc tune``'s).
    """
    robot = robot_key(robot)  # a .urdf path absolute: the file serves from any directory (analyze, ros2 run)
    run: dict[str, Any] = {"robot": robot, "contour": contour, "type": controller, "rate": float(rate)}
    own = {k: [float(x) for x in v] for k, v in gains.as_dict().items() if k in law(controller).gain_names}
    header = f"# pdsmc tune: {controller} gains for {robot}/{contour} at {float(rate):g} Hz"
    header += f", accepted by\n# {accepted_by}\n" if accepted_by else "\n"
    body = yaml.safe_dump({"/**": {"ros__parameters": run}, node: {"ros__parameters": own}}, sort_keys=False)
    Path(path).write_text(header + body)
