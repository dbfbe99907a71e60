"""Gains changed at run time (``ros2 param set``): the on-set callback validates a change (the
run it gives must pass the stability check), the post-set callback applies it."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..control import GAINS, Gains
from ..errors import ConfigError, PdsmcError
from ..parameters.ros import value_of
from ..presets import RunSpec, resolve_gains
from ..runtime.joint_map import JointMap


def check_gains(check: Callable[[RunSpec], object], spec: RunSpec) -> None:
    """``check(spec)`` (the stability check), anything it raises besides the package's own errors
    (a ``LinAlgError`` of gains of 1e308) a ConfigError naming the gains: at start-up a one-line
    error, on a set a refusal."""
    try:
        check(spec)
    except PdsmcError:
        raise
    except Exception as exc:  # noqa: BLE001 - numpy's, numba's: what the check could not foresee
        raise ConfigError(f"gains {spec.gains.as_dict()} cannot be checked for stability "
                          f"({type(exc).__name__}: {exc})") from None


class GainUpdates:
    """Run-time gain changes, ros2/demos style: the on-set callback validates, the
    post-set callback applies.

    A change is resolved as at start-up, by the one resolver
    (:func:`~pdsmc_ros.presets.resolve_gains`: the presets, the gains given as parameters with
    the change, in ``joints`` order, then the scenario's factors), and passes exactly the checks
    of start-up (:meth:`Gains.from_mapping`'s and the zero-order-hold stability check at the
    running rate, ``check``) or is refused with the reason (``ros2 param set`` shows it: for an
    unstable gain, the lowest stable rate). Whatever the check raises (a ``LinAlgError`` of gains
    of 1e308) is a refusal, never an exception in the executor. ``apply`` receives the accepted
    gains only after the parameters are set, from the post-set callback.
    """

    def __init__(self, node: Node, spec: RunSpec, check: Callable[[RunSpec], object],
                 apply: Callable[[Gains], None], *, joint_map: JointMap | None = None) -> None:
        self.spec = spec
        self.check = check
        self.apply = apply
        self.joint_order = None if joint_map is None else joint_map.user_of
        # the gains given as parameters at start (-p, params files), in joints order
        self.given: dict[str, Any] = {name: value_of(node, name) for name in GAINS if value_of(node, name) is not None}
        self.pending: tuple[Gains, dict[str, Any]] | None = None
        node.add_on_set_parameters_callback(self.validate)
        node.add_post_set_parameters_callback(self.applied)

    def validate(self, params: Sequence[Parameter]) -> SetParametersResult:
        self.pending = None
        changes = {p.name: p.value for p in params if p.name in GAINS}
        if not changes:
            return SetParametersResult(successful=True)
        given = {**self.given, **changes}
        spec = self.spec
        try:
            gains = resolve_gains(spec.robot, spec.contour, spec.controller, scenario=spec.scenario,
                                  layers=[given], joint_order=self.joint_order)
            check_gains(self.check, dataclasses.replace(spec, gains=gains))
        except Exception as exc:  # noqa: BLE001 - a refusal with the reason, never an escape into the executor
            reason = str(exc) if isinstance(exc, PdsmcError) else f"{', '.join(changes)}: {type(exc).__name__}: {exc}"
            return SetParametersResult(successful=False, reason=" ".join(reason.split()))
        self.pending = (gains, given)
        return SetParametersResult(successful=True)

    def applied(self, params: Sequence[Parameter]) -> None:
        if self.pending is None or not any(p.name in GAINS for p in params):
            return
        (gains, self.given), self.pending = self.pending, None
        self.spec = dataclasses.replace(self.spec, gains=gains)
        self.apply(gains)
