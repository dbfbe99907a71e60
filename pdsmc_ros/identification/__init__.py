"""Identification of an arm's dynamics from its own runs (ROS-free).

The path (docs/how-to/identify.md): :mod:`.excitation` designs the motion (a Fourier series at rest
at home at both ends, optimised for the conditioning of :mod:`.base`'s base regressor within the
limits); the run is recorded as any run; :mod:`.recording` reads its joint states and efforts by
joint name; :mod:`.identify` chains :mod:`.signals` (parallel filtering), :mod:`.estimate`
(weighted least squares with standard errors) and :mod:`.consistent` (an LMI per body); and
:mod:`.arm_files` writes the corrected URDF and its options file. The model is :mod:`.model`
(Pinocchio's regressor, a payload, each joint's motor inertia and friction); :mod:`.simulated`
runs an excitation in the project's simulator.
"""

from .base import BaseParameters, base_parameters
from .consistent import ConsistentFit, consistent_fit, is_consistent
from .estimate import BaseEstimate, NotIdentifiableError, weighted_least_squares
from .excitation import ExcitationLimits, FourierExcitation, excitation_limits, optimise_excitation
from .identify import Identification, identify, validate
from .model import ArmDynamics, ParameterLayout, arm_of
from .recording import JointRecording, RecordingError, read_joint_states

__all__ = [
    "ArmDynamics",
    "BaseEstimate",
    "BaseParameters",
    "ConsistentFit",
    "ExcitationLimits",
    "FourierExcitation",
    "Identification",
    "JointRecording",
    "NotIdentifiableError",
    "ParameterLayout",
    "RecordingError",
    "arm_of",
    "base_parameters",
    "consistent_fit",
    "excitation_limits",
    "identify",
    "is_consistent",
    "optimise_excitation",
    "read_joint_states",
    "validate",
    "weighted_least_squares",
]
