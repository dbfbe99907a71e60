"""Every node's parameters, declared once as data (ROS-free).

Each node's table is a tuple of :class:`~.declaration.ParameterSpec` built by a function, so
what changes with the registries -- the gains every registered law declares (a plugin law's
``ki`` among them), the laws and robots a parameter accepts -- is read when a node starts
or the documentation is generated. :mod:`.ros` declares a table on a node; :mod:`pdsmc_ros.parameters.params_file`
checks params files against the names; :func:`catalog` is the parameter reference.

Groups shared by several nodes: :func:`run_parameters` (the run: every node of a run takes the
same values, so one params file serves them all), :func:`gain_parameters` (every node declares
the gains; only the controller applies them, and only there can they change at run time),
``busy_wait`` and the real-time settings of a ticking node (:func:`realtime_parameters`).
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

from ..control.registry import GAINS
from ..control.soft_limits import DEFAULT_K_POSITION, SOFT_VELOCITY_BAND
from ..errors import ConfigError
from ..robots.catalog import allowed_robots
from .declaration import JOINT, ParameterSpec
from .run_table import run_parameters

P = ParameterSpec

# -- defaults and choices the components read from here (the table is their one source, as a
# -- controller reads generate_parameter_library's generated parameters) -------------------------
STOPPED_VELOCITY_TOLERANCE = 0.01
"""rad/s: joint_trajectory_controller's default goal velocity tolerance (``constraints.stopped_velocity_tolerance``)."""
START_TOLERANCE = 0.01
"""rad: MoveIt's ``trajectory_execution/allowed_start_tolerance`` default (``allowed_start_tolerance``)."""
RUNAWAY_STOPS = ("damp", "zero")
"""What the runaway guard outputs once tripped (``runaway.stop``)."""
DEFAULT_RUNAWAY_VELOCITY_FACTOR = 1.25
"""A joint faster than this many times its velocity limit trips the runaway guard: the soft
limits hold a well-behaved loop below the limit, so a quarter beyond it is a loop out of control
(a real drive's own overspeed fault typically sits there too)."""
DEFAULT_RUNAWAY_POSITION_MARGIN = 0.02
"""rad: a joint this far beyond a position limit trips the runaway guard (about one degree: beyond
encoder noise and the soft limits' small overshoot, well before a hard stop is reached)."""
SAFE_MODES = ("damp", "hold")
"""The plant's safe modes (``safe_mode``)."""
ON_LOSS = ("resume", "end")
"""What the plant does after safe mode (``on_controller_loss``)."""
MAX_SAFE_DAMPING = 1.0e6
"""N m s/rad: the highest ``safe_damping``: far above any useful value, low enough that the safe
torque stays finite."""
MAX_SAFE_STIFFNESS = 1.0e7
"""N m/rad: the highest ``safe_stiffness`` (as :data:`MAX_SAFE_DAMPING`)."""
DEFAULT_DISPLAY_RATE = 30.0
"""The viewer's frames per second of wall time (``display_rate``)."""
DEFAULT_COMMAND_TIMEOUT_S = 0.1
"""Seconds without a command after which the MuJoCo stand-in's brakes close (``command_timeout``):
a real arm's driver stops the arm when its commands stop (a watchdog), where ros2_control's
forward command controller would apply the last command forever. 0.1 s is 100 periods of a
1 kHz controller, far beyond its late ticks, and short enough that a dead controller's last
torque moves the arm little."""
JOINT_STATE_ORDERS = ("alphabetical", "urdf", "reversed")
"""The orders the MuJoCo stand-in can publish ``/joint_states`` in (``joint_state_order``)."""

INTROSPECTION_STATES = ("disabled", "metadata", "contents")
"""rcl's service introspection states (``RCL_SERVICE_INTROSPECTION_OFF``, ``_METADATA``, ``_CONTENTS``)."""
GOAL_PROCESS_CHOICES = ("auto", "always", "never")
"""Where a real-time controller serves its action and parameters (``goal_process:=``)."""

NODES = ("controller", "plant", "trajectory", "recorder", "mujoco_driver", "viewer")
"""The package's nodes: one params file may configure several of them (``run_experiment.sh``
hands the same file to each)."""

LOOKAHEAD_STEPS = 500
"""The trajectory's ``lookahead_steps`` default (lockstep: 50 ms at 10 kHz)."""
MAX_LOOKAHEAD_STEPS = 5000
"""Half the depth of the lockstep streams' queues (:data:`pdsmc_ros.ros.topics.STREAM_DEPTH`)."""


def gain_parameters(*, applied: bool | Collection[str]) -> tuple[ParameterSpec, ...]:
    """One parameter per gain a registered law declares (:data:`pdsmc_ros.control.registry.GAINS`,
    its :class:`~pdsmc_ros.control.registry.GainSpec`): a double array of one value per joint (one
    value: every joint), or a double for a gain with one value for every joint. ``applied``: the
    node applies a change at run time (the controller: True for the reference, else the names of
    its law's gains); the others are read-only (every node declares every gain so that one params
    file serves every node and every law)."""
    return tuple(
        P(g.name, "double_array" if g.per_joint else "double", None, g.help(), lo=g.lower, lo_open=g.lower_open,
          hi=None if g.upper == float("inf") else g.upper, per_joint=g.per_joint, one_for_all=True,
          read_only=not (applied is True or (not isinstance(applied, bool) and g.name in applied)))
        for g in GAINS.values()
    )


DEFAULT_PRIORITY = 50
"""``thread_priority``'s default in real time for the controller: ros2_control's controller manager's
SCHED_FIFO 50."""
PLANT_PRIORITY = DEFAULT_PRIORITY - 1
"""... for the plant (the hardware's stand-in, the MuJoCo driver too) and, below it, the trajectory
(:data:`TRAJECTORY_PRIORITY`): they tick at SCHED_FIFO just below the controller, so that when three
loop processes contend for two cores the controller goes first (docs/PERFORMANCE.md)."""
TRAJECTORY_PRIORITY = DEFAULT_PRIORITY - 2
MAX_PRIORITY = 99
"""The highest SCHED_FIFO priority Linux gives."""
AUTO_BUSY_WAIT = -1.0
"""``busy_wait``'s default: chosen from the loop's scheduling and how many loops share its thread
(:func:`pdsmc_ros.loop.realtime.busy_wait_for`)."""


BUSY_WAIT = P(
    "busy_wait", "double", AUTO_BUSY_WAIT,
    "real time: seconds before each tick spent busy-waiting instead of sleeping (absorbs late wake-ups, costs that "
    "share of a core); -1 (default): 0.0002 at normal priority, at SCHED_FIFO 0.00005, 0.0003 for a process "
    "ticking several loop nodes; at SCHED_FIFO at most half a period",
    lo=0.0, hi=1.0, special=(AUTO_BUSY_WAIT,), constraints="-1 (automatic) or a number of seconds in [0, 1]")

STABILITY = (
    P("stability_margin", "double", 0.0,
      "required control rate / lowest stable rate of the gains (0: the mode's, 2 realtime, 1 lockstep)",
      lo=0.0, hi=1.0e6),
    P("delay_periods", "int", 0,
      "periods of delay beyond the mode's own that the stability check models (a driver's)", lo=0, hi=1000),
)
"""The controller's: what :func:`~pdsmc_ros.control.stability.check_rate` requires of its gains."""

CONTROLLER = (
    P("joints", "string_array", None,
      "the controlled joints by name, any order (default: the robot's actuated joints in URDF order); the order "
      "of the command's data, of gains and torque_limit given as parameters and of every per-joint output",
      constraints="a list of the robot's actuated joint names, each once"),
    P("autostart", "bool", True, "configure and activate at start (false: wait for the lifecycle transitions)"),
    P("torque_limit", "double_array", None,
      "per-joint torque limits in N m, joints order (default: the arm's effort limits)", lo=0.0, lo_open=True,
      per_joint=True),
    P("enforce_limits", "bool", True,
      "clamp torques to the limits and refuse trajectories outside the joint limits (false: opt out of both)"),
    P("stale_periods", "int", 20, "real time: periods after which a state or reference is stale", lo=1, hi=10**6),
    P("constraints.goal_time", "double", 0.0,
      "action goals: default goal_time_tolerance in s (0: wait for the goal tolerances)", lo=0.0),
    P("constraints.stopped_velocity_tolerance", "double", STOPPED_VELOCITY_TOLERANCE,
      "action goals: default goal velocity tolerance in rad/s (0: not checked)", lo=0.0),
    P(f"constraints.{JOINT}.trajectory", "double", 0.0, f"default trajectory position tolerance of {JOINT} in rad",
      lo=0.0, map_joints=True),
    P(f"constraints.{JOINT}.goal", "double", 0.0, f"default goal position tolerance of {JOINT} in rad", lo=0.0,
      map_joints=True),
    P("constraints.decelerate_on_cancel", "bool", False,
      "on a cancel or an abort, brake each joint at constraints.<joint>.max_deceleration_on_cancel to rest before "
      "holding (JTC's decelerate_on_cancel; false: hold at once)"),
    P(f"constraints.{JOINT}.max_deceleration_on_cancel", "double", 0.0,
      f"rad/s^2: {JOINT}'s deceleration when constraints.decelerate_on_cancel brakes (0 on any joint: hold at once)",
      lo=0.0, map_joints=True),
    P("cmd_timeout", "double", 0.0, "hold the measured position this long (s) after a trajectory's last point "
      "(0: never; ignored unless above constraints.goal_time)", lo=0.0),
    P("allowed_start_tolerance", "double", START_TOLERANCE, "beyond JTC: a trajectory whose reference at receipt "
      "is more than this (rad) from the current position is a step", lo=0.0),
    P("allow_partial_joints_goal", "bool", False, "accept trajectories naming some of the joints (the others hold)"),
    P("allow_nonzero_velocity_at_trajectory_end", "bool", False, "accept trajectories whose last point moves"),
    P("reject_beyond_limits", "bool", True,
      "beyond JTC: reject trajectories beyond the arm's limits or with a step"),
    P("action_introspection", "string", "contents",
      "accepted action goals published as SendGoal service events on <action>/_action/send_goal/_service_event "
      "(as ROS 2 service introspection does; a recorder records them): disabled, metadata (no trajectory) or "
      "contents", choices=INTROSPECTION_STATES),
    P("goal_process", "string", "auto",
      "real time: the action server, ~/joint_trajectory's validation and the parameter services in a process of "
      "their own (always: the loop's interpreter lock free of a storm of clients, at the cost of a core's share), "
      "in a thread of the controller's process (never), or auto: a process of their own when the controller may "
      "run on 2 or more cores "
      "(docs/explanation/realtime.md: what each costs and buys on 2 cores)", choices=GOAL_PROCESS_CHOICES),
)
"""The controller's own (besides the run's, the gains and the stability check's)."""

OUTPUT_LIMITS = (
    P("soft_limits.k_position", "double", DEFAULT_K_POSITION,
      "soft limits: allowed velocity toward a position limit per rad of distance to it (1/s; ros2_control's "
      "k_position)", lo=0.0),
    P("soft_limits.k_velocity", "double_array", None,
      "soft limits: per joint, joints order, the effort bound's slope beyond the velocity bound (N m s/rad; "
      f"ros2_control's k_velocity); default effort limit / ({SOFT_VELOCITY_BAND:g} x velocity limit): the whole "
      "effort up to 90 % of the velocity limit", lo=0.0, per_joint=True),
    P("runaway.velocity_factor", "double", DEFAULT_RUNAWAY_VELOCITY_FACTOR,
      "real time: a joint faster than this many times its velocity limit stops the motion", lo=0.0, lo_open=True),
    P("runaway.position_margin", "double", DEFAULT_RUNAWAY_POSITION_MARGIN,
      "real time: a joint this far beyond a position limit stops the motion (rad)", lo=0.0),
    P("runaway.stop", "string", "damp", "real time: the output once the runaway guard tripped: damp (a damping "
      "torque that brings the arm to rest) or zero (no torque)", choices=RUNAWAY_STOPS),
)
"""The controller's output limits: ros2_control's soft limits and the runaway guard (none applies
with ``enforce_limits:=false``)."""

SAFETY = (
    P("watchdog_timeout", "double", 2.0,
      "lockstep: wall-clock seconds without effort before safe mode (checked every 20 ms)", lo=0.05, hi=3600.0),
    P("watchdog_periods", "int", 20, "real time: control periods without effort before safe mode", lo=1),
    P("safe_mode", "string", "damp", "safe mode: damp (braking only) or hold (hold position)", choices=SAFE_MODES),
    P("safe_damping", "double", 5.0, "safe-mode braking gain in N m s/rad", lo=0.0, hi=MAX_SAFE_DAMPING),
    P("safe_stiffness", "double", 200.0, "hold-mode stiffness in N m/rad", lo=0.0, hi=MAX_SAFE_STIFFNESS),
    P("on_controller_loss", "string", "resume", "after safe mode", choices=ON_LOSS),
    P("safe_time_scale", "double", 1.0,
      "lockstep: sim seconds the plant advances per wall second in safe mode (1: real time, 0: frozen)",
      lo=0.0, hi=1000.0),
)
"""The plant's watchdog and safe mode."""

PLANT = (
    P("expected_subscribers", "int", 3, "subscribers of /joint_states to wait for (trajectory, controller, recorder)",
      lo=0, hi=100),
    P("enforce_limits", "bool", True, "clamp the applied torque to the arm's effort limits (false: opt out)"),
)

TRAJECTORY = (
    P("expected_subscribers", "int", 2, "subscribers of /reference to wait for (controller, recorder)", lo=0, hi=100),
    P("lookahead_steps", "int", LOOKAHEAD_STEPS, "lockstep: references published ahead of the plant's state",
      lo=1, hi=MAX_LOOKAHEAD_STEPS),
)

RECORDER = (P("output", "string", "", "the new bag directory to write"),)

MAX_DISPLAY_RATE = 240.0
"""The viewer's highest ``display_rate`` (frames per second of wall time)."""

VIEWER = (
    P("port", "int", 8765, "WebSocket port of the Foxglove server (0: any free)", lo=0, hi=65535),
    P("host", "string", "127.0.0.1", "address the Foxglove server listens on"),
    P("display_rate", "double", DEFAULT_DISPLAY_RATE, "frames per second of wall time", lo=0.0, lo_open=True,
      hi=MAX_DISPLAY_RATE),
)


def realtime_parameters(priority: int = DEFAULT_PRIORITY) -> tuple[ParameterSpec, ...]:
    """The real-time settings of a ticking node, named as ros2_control's (applied once, before the
    loop starts: read-only). Their defaults depend on the mode (:meth:`RealtimeSettings.for_mode
    <pdsmc_ros.loop.realtime.RealtimeSettings.for_mode>`): the node gives them when it declares."""
    return (
        P("thread_priority", "int", 0,
          f"SCHED_FIFO priority of the loop's thread, 1-{MAX_PRIORITY} (0: normal scheduling; default {priority} in "
          f"real time: the controller {DEFAULT_PRIORITY}, as ros2_control's controller manager, the plant "
          f"{PLANT_PRIORITY} and the trajectory {TRAJECTORY_PRIORITY} just below it)",
          lo=0, hi=MAX_PRIORITY, constraints=f"a whole number in [0, {MAX_PRIORITY}] (0: normal scheduling)"),
        P("cpu_affinity", "int_array", [-1], "cores the loop's thread may run on, e.g. [1] (default [-1]: any core)",
          lo=-1, one_for_all=True, constraints="a list of core numbers, e.g. [1], or [-1] for any core"),
        P("lock_memory", "bool", False,
          "lock the process's present and future memory pages (mlockall; default on in real time)"),
    )


REALISM_PRESETS = ("ideal", "bench")
"""The MuJoCo stand-in's named presets of its nuisances (``realism:=``; :mod:`pdsmc_ros.sim.realism`)."""
VELOCITY_SOURCES = ("exact", "difference")
"""``exact``: the simulator's joint velocity; ``difference``: the backward difference of the published
positions over one period, as many drives compute it (then ``velocity_filter_hz``)."""
MAX_COMMAND_DELAY = 100
"""Ticks a command may be delayed at most (0.1 s at 1 kHz; the drive's delay line holds this many)."""
UNSET_IS_PRESET = "; unset: the realism preset's"

REALISM = (
    P("realism", "string", "ideal", "the named preset of every nuisance below: ideal (every one off: the stand-in "
      "as a perfect arm) or bench (an arm like the one on the bench, docs/how-to/mujoco.md); a nuisance given "
      "explicitly replaces the preset's", choices=REALISM_PRESETS),
    P("seed", "int", 0, "seed of every random draw of the nuisances (the position noise): a run repeats exactly",
      lo=0, hi=2**63 - 1),
    P("friction_coulomb", "double_array", None, "Coulomb (dry) friction of each joint in N m, MuJoCo's frictionloss "
      "with a stiff solref_friction (two timesteps)" + UNSET_IS_PRESET, lo=0.0, hi=10**6, per_joint=True,
      one_for_all=True, read_only=False),
    P("friction_viscous", "double_array", None, "viscous friction of each joint in N m s/rad, added to the URDF's "
      "<dynamics damping>" + UNSET_IS_PRESET, lo=0.0, hi=10**6, per_joint=True, one_for_all=True, read_only=False),
    P("encoder_counts", "int_array", None, "counts per revolution of each joint's encoder (per metre: a prismatic "
      "joint): the published position is the nearest count (the ideal preset has none: exact)" + UNSET_IS_PRESET,
      lo=1, hi=2**40, per_joint=True, one_for_all=True, read_only=False),
    P("position_noise", "double_array", None, "standard deviation in rad of the Gaussian noise added to each "
      "published position, before the encoder's grid" + UNSET_IS_PRESET, lo=0.0, hi=1.0, per_joint=True,
      one_for_all=True, read_only=False),
    P("velocity_source", "string", None, "the published velocity: exact (the simulator's) or difference (the "
      "backward difference of the published positions over one period, as many drives compute it)"
      + UNSET_IS_PRESET, choices=VELOCITY_SOURCES, read_only=False),
    P("velocity_filter_hz", "double_array", None, "cut-off in Hz of the first-order low-pass filter of the "
      "differenced velocity (libfranka's discretisation; 0: none)" + UNSET_IS_PRESET, lo=0.0, hi=10**6,
      per_joint=True, one_for_all=True, read_only=False),
    P("command_delay", "int", None, "ticks between a command's arrival and the torque it sets: the motors apply "
      "the command that arrived this many periods earlier" + UNSET_IS_PRESET, lo=0, hi=MAX_COMMAND_DELAY,
      read_only=False),
    P("torque_bandwidth_hz", "double_array", None, "bandwidth in Hz of a first-order lag of each motor's torque "
      "behind its command (the drive's current loop; 0: none)" + UNSET_IS_PRESET, lo=0.0, hi=10**6, per_joint=True,
      one_for_all=True, read_only=False),
    P("torque_speed", "bool", None, "the motors' torque falls linearly with speed, from the effort limit at rest "
      "to zero at no_load_speed (a DC motor's torque-speed line)" + UNSET_IS_PRESET, read_only=False),
    P("no_load_speed", "double_array", None, "speed in rad/s at which each motor's torque reaches zero "
      "(torque_speed; by default twice the joint's URDF velocity limit)" + UNSET_IS_PRESET, lo=0.0, lo_open=True,
      hi=10**6, per_joint=True, one_for_all=True, read_only=False),
    P("payload_mass", "double", None, "a load in kg fixed to the tool frame, which the controller's model does not "
      "know" + UNSET_IS_PRESET, lo=0.0, hi=10**4),
    P("payload_com", "double_array", None, "where the load's centre of mass is, in m in the tool frame"
      + UNSET_IS_PRESET, lo=-10.0, hi=10.0, constraints="3 numbers (x, y, z), each in [-10, 10]"),
)
"""The MuJoCo stand-in's nuisances, its ``realism`` preset and ``seed`` (:mod:`pdsmc_ros.sim.realism`
resolves and checks them with these declarations; the ``--plant mujoco`` runs' flags are made from
them). Unset, a nuisance is the preset's; those not read-only the driver applies while it runs,
checked against the arm first (its node's on-set check)."""


def realism_parameters() -> tuple[ParameterSpec, ...]:
    """:data:`REALISM`."""
    return REALISM


def mujoco_driver_parameters() -> tuple[ParameterSpec, ...]:
    """The MuJoCo stand-in's (a driver of its own: no run, no gains)."""
    return (
        P("robot", "string", "serial_3r", "the arm: " + allowed_robots()),
        P("rate", "double", 1000.0, "state rate and physics period in Hz", lo=1.0, hi=20000.0),
        P("substeps", "int", 1, "MuJoCo steps per period", lo=1, hi=1000),
        P("joint_state_order", "string", "alphabetical", "order of /joint_states", choices=JOINT_STATE_ORDERS),
        P("joints", "string_array", None, "joint of each command entry (default: the arm's actuated joints)"),
        P("initial_positions", "double_array", None,
          "initial angles of the actuated joints, robot order (default: a URDF arm's home, a thesis arm at its "
          "circle contour's start)", per_joint=True),
        P("command_timeout", "double", DEFAULT_COMMAND_TIMEOUT_S,
          "seconds without a command after which the brakes close again, as a real driver's watchdog (0: never, "
          "as a forward command controller)", lo=0.0, hi=3600.0),
        *realism_parameters(),
        BUSY_WAIT,
    )


def node_parameters(node: str) -> tuple[ParameterSpec, ...]:
    """Every parameter ``node`` (one of :data:`NODES`) declares, in declaration order."""
    run = (*run_parameters(), *gain_parameters(applied=node == "controller"), BUSY_WAIT)
    tables = {
        "controller": lambda: (*run, *STABILITY, *CONTROLLER, *OUTPUT_LIMITS, *realtime_parameters(DEFAULT_PRIORITY)),
        "plant": lambda: (*run, *SAFETY, *PLANT, *realtime_parameters(PLANT_PRIORITY)),
        "trajectory": lambda: (*run, *TRAJECTORY, *realtime_parameters(TRAJECTORY_PRIORITY)),
        "recorder": lambda: (*run, *RECORDER, *realtime_parameters(0)),
        "viewer": lambda: (*run, *VIEWER),
        "mujoco_driver": lambda: (*mujoco_driver_parameters(), *realtime_parameters(PLANT_PRIORITY)),
    }
    if node not in tables:
        raise ConfigError(f"unknown node {node!r}; choose one of: {', '.join(NODES)}")
    return tables[node]()


def catalog() -> dict[str, list[dict[str, Any]]]:
    """Every node's parameters as plain data (``{node: [{name, type, default, description, allowed,
    lower, upper, choices, per_joint, read_only, ...}, ...]}``): the documentation's parameter
    reference. Gains of laws registered at the time of the call are included."""
    return {node: [spec.as_dict() for spec in node_parameters(node)] for node in NODES}


def parameter_names(node: str) -> tuple[str, ...]:
    """The names ``node`` declares (gains included)."""
    return tuple(spec.name for spec in node_parameters(node))


def package_parameter_names() -> frozenset[str]:
    """Every parameter some node of the package declares (a shared params-file section may give
    one that only other nodes of the run take)."""
    return frozenset(name for node in NODES for name in parameter_names(node))
