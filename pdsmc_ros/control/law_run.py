"""What the laws and their checks read of a run: a protocol, so the laws need not know how runs are built.

:class:`pdsmc_ros.runs.builder.RunSpec` provides it; :mod:`.law`, :mod:`.stability` and :mod:`.lyapunov`
take any object that does (they import nothing from the run builder above them).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from ..robots.base import FloatArray, Manipulator

if TYPE_CHECKING:
    from ..contours import JointReference
    from .registry import Gains


class LawRun(Protocol):
    """A run as its law sees it: names, rates, gains and the models."""

    @property
    def robot(self) -> str:
        """The robot's name (messages)."""

    @property
    def contour(self) -> str:
        """The contour's name (messages)."""

    @property
    def controller(self) -> str:
        """The registered law."""

    @property
    def gains(self) -> Gains:
        """The law's gains (after the scenario's factors)."""

    @property
    def rate(self) -> float:
        """Control rate (Hz)."""

    @property
    def sample_rate(self) -> float:
        """Statistics rate (Hz): a suggested rate is a multiple of it."""

    def robot_model(self) -> Manipulator:
        """The simulated plant."""

    def nominal_model(self) -> Manipulator:
        """The model known to the law."""

    def reference(self) -> JointReference:
        """The desired joint motion."""

    def smc_model_vector(self) -> FloatArray:
        """The model estimate's scales (:attr:`pdsmc_ros.control.LawSetup.smc_model`)."""
