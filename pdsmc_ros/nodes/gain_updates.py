"""Gains changed at run time (``ros2 param set``): the on-set callback validates a change (the
run it gives must pass the stability check), the post-set callback applies it."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..checks import is_real
from ..control import GAINS, Gains
from ..errors import InvalidInputError
from ..presets import RunSpec, scenario_gain_factors
from .params import RUN_PARAMETERS


class GainUpdates:
    """Run-time gain changes, ros2/demos style: the on-set callback validates, the
    post-set callback applies.

    A change passes exactly the checks of start-up (:meth:`Gains.from_mapping`
    and the zero-order-hold stability check at the running rate,
    :func:`~pdsmc_ros.control.stability.check_rate`) or is refused with the reason
    (``ros2 param set`` shows it: for an unstable gain, the lowest stable
    rate). ``apply`` receives the accepted gains only after the parameters are
    set, from the post-set callback.
    """

    def __init__(self, node: Node, spec: RunSpec, check: Callable[[RunSpec], object],
                 apply: Callable[[Gains], None]) -> None:
        self.spec = spec
        self.check = check
        self.apply = apply
        self.pending: Gains | None = None
        node.add_on_set_parameters_callback(self.validate)
        node.add_post_set_parameters_callback(self.applied)

    def validate(self, params: list[Parameter]) -> SetParametersResult:
        merged = self.spec.gains.as_dict()
        factors = scenario_gain_factors(self.spec.scenario, self.spec.controller)
        changed = False
        for param in params:
            if param.name in GAINS:
                value = param.value
                scalar = is_real(value)
                merged[param.name] = [value] if scalar else list(value or [])
                changed = True
            elif param.name in RUN_PARAMETERS or param.name in ("joints", "autostart"):
                return SetParametersResult(
                    successful=False,
                    reason=f"{param.name} defines the run and cannot change while it runs",
                )
        self.pending = None
        if not changed:
            return SetParametersResult(successful=True)
        try:
            gains = Gains.from_mapping({k: v for k, v in merged.items() if v}, self.spec.gains.n,
                                       self.spec.controller)
            # as at start: the scenario's factors apply to the gains given
            gains = gains.scaled({k: f for k, f in factors.items() if any(p.name == k for p in params)})
            self.check(dataclasses.replace(self.spec, gains=gains))
        except (InvalidInputError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.pending = gains
        return SetParametersResult(successful=True)

    def applied(self, params: list[Parameter]) -> None:
        if self.pending is None or not any(p.name in GAINS for p in params):
            return
        gains, self.pending = self.pending, None
        self.spec = dataclasses.replace(self.spec, gains=gains)
        self.apply(gains)
