"""Parameter overrides a node does not declare: a warning for ``-p``, an error for a params file.

rclpy keeps an override of an undeclared parameter and never says so (``-p typ:=pd`` ran the
default law), and rcl skips a params file's sections that match no node. After the nodes of a
process are built (:func:`~pdsmc_ros.loop.process.run_nodes`), every params file given must
have a section for one of them and no key the matching node does not declare
(:mod:`pdsmc_ros.parameters.params_file`), and each ``-p`` override left undeclared is warned about, naming
the closest declared parameter (every name some node declares: the tables of :mod:`pdsmc_ros.parameters`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from rclpy.node import Node

from ..rclpy_internals import parameter_overrides
from . import package_parameter_names
from .params_file import (
    ALWAYS_DECLARED,
    is_declared,
    node_parameters,
    param_arguments,
    params_files_in,
    read_params_file,
    section_matches,
    unknown_parameter,
)


def declared_names(node: Node) -> list[str]:
    """Every parameter ``node`` declares."""
    return list(node.list_parameters([], 0).names)


def check_overrides(nodes: Sequence[Node], args: Sequence[str] | None) -> None:
    """Refuse params files with no section for these nodes or with keys they do not declare;
    warn (on the node's logger) about each undeclared ``-p`` override.

    Raises
    ------
    ConfigError
        One line naming the file, the section and the key (with the closest declared name).
    """
    files = params_files_in(sys.argv if args is None else args)
    for path in files:
        sections = read_params_file(path)
        matched = [node for node in nodes
                   if any(section_matches(s, node.get_fully_qualified_name()) for s in sections)]
        for node in matched or nodes[:1]:  # none matched: the first node's error names the file's sections
            node_parameters(path, node.get_fully_qualified_name(), declared_names(node), sections=sections)
    for node in nodes:
        declared = declared_names(node)
        try:
            overrides = parameter_overrides(node)
        except AttributeError:  # another rclpy: no warning rather than no node
            overrides = {}
        for name in overrides:
            if not is_declared(name, declared):
                node.get_logger().warning(f"{unknown_parameter(name, declared)}: ignored")


def warn_unknown_arguments(name: str, args: Sequence[str] | None) -> None:
    """When a node could not be built: warn about each ``-p NAME:=VALUE`` no node of the package
    declares (the build's own error may be a consequence: ``-p typ:=pd`` left the default law,
    whose gains were then refused)."""
    args = list(sys.argv if args is None else args)
    known = [*package_parameter_names(), *ALWAYS_DECLARED]
    for _, key, _ in param_arguments(args):  # node:name:=value names a node's parameter
        if not is_declared(key, known):
            print(f"{name}: warning: {unknown_parameter(key, known)}: ignored", file=sys.stderr, flush=True)

