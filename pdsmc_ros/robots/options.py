"""The options of a URDF arm (the YAML beside its URDF, a catalog entry, a ``<pdsmc_ros>`` element),
checked: keys and types here (:func:`check_entry`), per-joint lengths once the joints are known
(:func:`per_joint`, :func:`position_pairs`, called by :func:`.urdf_robot.urdf_arm`).
Every problem is one line naming where the options came from and the key.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..checks import are_real, is_real
from ..errors import ConfigError, InvalidInputError
from .base import FloatArray

OPTION_KEYS = ("armature", "ee_frame", "locked_joints", "home", "plane", "orientation", "effort_limits",
               "velocity_limits", "position_limits", "friction_coulomb", "friction_viscous", "payload_mass",
               "payload_com")
"""The task and model options of an arm. ``friction_coulomb``, ``friction_viscous``, ``payload_mass`` and
``payload_com`` are the MuJoCo stand-in's own parameter names (what ``pdsmc identify`` writes): Coulomb
and viscous friction per joint (N m, N m s; the viscous adds to the URDF's ``<dynamics damping>``), a
point mass (kg) at ``payload_com`` (m, in the end-effector frame)."""
SETTING_KEYS = ("control_rate", "sample_rate", "contour_bound", "contour_size", "contours", "gains")


def robot_key(name: str) -> str:
    """The one spelling of a robot: a ``.urdf`` path (relative, absolute or ``~/...``) as its
    absolute path, ``~`` expanded and symbolic links followed; any other name (a registered
    robot, an arm of the catalog) as given. The registry keeps a path's arm under it
    (:func:`~.catalog.resolve_robot`), a params file names it (``pdsmc tune``), and
    :func:`same_robot` compares by it."""
    if isinstance(name, str) and name.lower().endswith(".urdf"):
        return str(Path(name).expanduser().resolve())
    return name


def same_robot(a: object, b: object) -> bool:
    """Whether two spellings name one robot (:func:`robot_key`)."""
    return isinstance(a, str) and isinstance(b, str) and robot_key(a) == robot_key(b)


def check_entry(entry: Mapping[str, Any], where: str) -> None:
    """The keys and types of an arm's options (lengths against the joints: :func:`.urdf_robot.urdf_arm`).

    Raises
    ------
    ConfigError
        One line naming ``where`` (the options file) and the key: an unknown key (the
        allowed ones listed), or a value of the wrong type.
    """
    unknown = sorted(set(entry) - set(OPTION_KEYS) - set(SETTING_KEYS))
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown}; allowed: {', '.join(OPTION_KEYS + SETTING_KEYS)}")
    for key in ("ee_frame", "orientation", "contours"):
        if entry.get(key) is not None and not isinstance(entry[key], str):
            raise ConfigError(f"{where}: {key} must be a name (a string), got {entry[key]!r}")
    locked = entry.get("locked_joints")
    if locked is not None and (not isinstance(locked, list) or not all(isinstance(j, str) for j in locked)):
        raise ConfigError(f"{where}: locked_joints must be a list of joint names, got {locked!r}")
    plane = entry.get("plane")
    if plane is not None and (not isinstance(plane, dict) or set(plane) != {"origin", "u", "v"} or not all(
            isinstance(v, list) and len(v) == 3 and are_real(v) for v in plane.values())):
        raise ConfigError(f"{where}: plane must give origin, u and v (3 numbers each), got {plane!r}")
    for key in ("control_rate", "sample_rate", "contour_bound"):
        if key in entry and not (is_real(entry[key]) and 0.0 < entry[key] < float("inf")):
            raise ConfigError(f"{where}: {key} must be a number > 0, got {entry[key]!r}")
    size = entry.get("contour_size")
    if size is not None and not (is_real(size) and 0.0 < size < float("inf")):
        raise ConfigError(f"{where}: contour_size must be a number > 0 (m) or null, got {size!r}")
    mass = entry.get("payload_mass")
    if mass is not None and not (is_real(mass) and 0.0 <= mass < float("inf")):
        raise ConfigError(f"{where}: payload_mass must be a number >= 0 (kg), got {mass!r}")
    com = entry.get("payload_com")
    if com is not None and not (isinstance(com, list) and len(com) == 3 and are_real(com)
                                and all(np.isfinite(com))):
        raise ConfigError(f"{where}: payload_com must be 3 finite numbers (m, in the end-effector frame), got {com!r}")
    gains = entry.get("gains")
    if gains is not None and not isinstance(gains, (str, dict)):
        raise ConfigError(f"{where}: gains must name a table of config/gains.yaml or give one (contour group -> "
                          f"controller -> kp, kd, ...), got {gains!r}")


def per_joint(value: Any, names: Sequence[str], key: str, where: str, *, lowest: float | None = None,
              above: float | None = None, finite: bool = False, single: bool = True) -> FloatArray:
    """``value`` as one float per joint of ``names`` (one number for all when ``single``).

    Raises
    ------
    InvalidInputError
        One line naming ``where``, ``key``, the joint count and what was given.
    """
    n = len(names)
    wanted = f"{n} numbers (one per joint: {', '.join(names)})" + (" or one number for all" if single else "")
    if isinstance(value, (bool, str, Mapping)) or value is None:
        raise InvalidInputError(f"{where}: {key} needs {wanted}, got {value!r}")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{where}: {key} needs {wanted}, got {value!r}") from None
    if arr.ndim == 0 and single:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        got = f"{arr.size} values" if arr.ndim == 1 else repr(value)
        raise InvalidInputError(f"{where}: {key} needs {wanted}, got {got}")
    bad = np.isnan(arr) | (~np.isfinite(arr) if finite else False)
    if lowest is not None:
        bad |= arr < lowest
    if above is not None:
        bad |= arr <= above
    if np.any(bad):
        i = int(np.argmax(bad))
        rule = "finite" if finite else "a number"
        rule += f" >= {lowest:g}" if lowest is not None else f" > {above:g}" if above is not None else ""
        raise InvalidInputError(f"{where}: {key} of joint {names[i]!r} must be {rule}, got {float(arr[i])!r}")
    return arr


def position_pairs(value: Any, names: Sequence[str], where: str) -> FloatArray:
    """``position_limits``: one ``[lower, upper]`` pair per joint, lower < upper.

    Raises
    ------
    InvalidInputError
        One line naming ``where``, the key, the joint count or the joint whose pair is wrong.
    """
    n = len(names)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = np.empty(0)
    if isinstance(value, (bool, str, Mapping)) or arr.shape != (n, 2):
        raise InvalidInputError(f"{where}: position_limits needs {n} pairs [lower, upper] (one per joint: "
                                f"{', '.join(names)}), got {value!r}")
    bad = np.isnan(arr).any(axis=1) | (arr[:, 0] >= arr[:, 1])
    if np.any(bad):
        i = int(np.argmax(bad))
        raise InvalidInputError(f"{where}: position_limits of joint {names[i]!r} must be [lower, upper] with "
                                f"lower < upper, got {list(value[i])!r}")
    return arr
