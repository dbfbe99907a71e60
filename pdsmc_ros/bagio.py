"""Reading recorded runs back from rosbag2 MCAP bags (rosbags; no rclpy needed).

The recorder writes the CDR bytes it received; this module turns a bag into
per-step arrays and a :class:`~pdsmc_ros.presets.RunSpec`, and computes the
thesis statistics with the same code as the in-process simulator.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import BagError
from .metrics import Metrics, Samples, compute_metrics
from .models import FloatArray
from .presets import RunSpec

DESCRIPTION_KEY = "pdsmc_ros.run_description"
_CDR_HEADER = 4


def header_step(data: bytes, rate: float) -> int:
    """Control step of a CDR message that starts with ``std_msgs/Header``."""
    sec, nanosec = struct.unpack_from("<iI", data, _CDR_HEADER)
    return int(round((sec + nanosec * 1e-9) * rate))


def effort_step(data: bytes) -> int:
    """``layout.data_offset`` of a CDR ``std_msgs/Float64MultiArray`` (no dimensions)."""
    (dims,) = struct.unpack_from("<I", data, _CDR_HEADER)
    if dims != 0:
        raise BagError("effort messages with layout dimensions are not produced by pdsmc_ros")
    (offset,) = struct.unpack_from("<I", data, _CDR_HEADER + 4)
    return int(offset)


@dataclass
class RecordedRun:
    """Per-step signals of a lockstep bag (row ``k`` = control step ``k``)."""

    spec: RunSpec
    description: dict[str, Any]
    q: FloatArray
    qd: FloatArray
    q_ref: FloatArray
    tau: FloatArray
    counts: dict[str, int]
    missing: dict[str, int]
    complete: bool

    @property
    def steps(self) -> int:
        return len(self.q) - 1


def read_run(path: str | Path) -> RecordedRun:
    """Read a bag written by the recorder.

    Raises
    ------
    BagError
        If the path is not a readable bag or holds no run description.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if not path.exists():
        raise BagError(f"bag {str(path)!r} does not exist")
    typestore = get_typestore(Stores.ROS2_JAZZY)
    try:
        reader = AnyReader([path], default_typestore=typestore)
        reader.open()
    except Exception as exc:  # noqa: BLE001 - rosbags raises several unrelated types
        raise BagError(f"cannot read bag {str(path)!r}: {exc}") from None
    try:
        by_topic: dict[str, list[tuple[int, Any]]] = {}
        description: dict[str, Any] | None = None
        for connection, _timestamp, raw in reader.messages():
            topic = connection.topic
            if topic == "/pdsmc/run_description":
                msg = reader.deserialize(raw, connection.msgtype)
                description = json.loads(msg.data)
                continue
            if topic in ("/joint_states", "/reference", "/effort_controller/commands"):
                by_topic.setdefault(topic, []).append((raw, reader.deserialize(raw, connection.msgtype)))
    finally:
        reader.close()
    if description is None:
        raise BagError(f"bag {str(path)!r} holds no /pdsmc/run_description: not a pdsmc_ros run")
    spec = RunSpec.from_description(description)
    n = len(spec.gains.kp)
    rate = spec.rate
    steps = int(round(description["duration_s"] * rate))
    q = np.full((steps + 1, n), np.nan)
    qd = np.full((steps + 1, n), np.nan)
    q_ref = np.full((steps + 1, n), np.nan)
    tau = np.full((steps + 1, n), np.nan)
    counts = {}
    applied = np.full((steps + 1, n), np.nan)  # torque held over the period ending at k
    for raw, msg in by_topic.get("/joint_states", []):
        k = header_step(raw, rate)
        if 0 <= k <= steps:
            q[k] = msg.position[:n]
            qd[k] = msg.velocity[:n]
            applied[k] = msg.effort[:n]
    for raw, msg in by_topic.get("/reference", []):
        k = header_step(raw, rate)
        if 0 <= k <= steps and len(msg.points):
            q_ref[k] = msg.points[0].positions
    for raw, msg in by_topic.get("/effort_controller/commands", []):
        k = effort_step(raw)
        if 0 <= k <= steps:
            tau[k] = msg.data
    if description.get("mode") == "realtime":
        # In real time the controller's commands are tagged with the state it last saw and
        # the plant applies whichever is newest at its tick: the torque actually applied
        # over [k, k+1] is the effort the plant reports with state k+1. The reference is
        # recomputed from the run description (the trajectory node publishes the same
        # values, but not necessarily for every plant step).
        tau = np.vstack([applied[1:], np.full((1, n), np.nan)])
        tau[-1] = tau[-2]
        q_ref = spec.reference().sample(np.arange(steps + 1) / rate).q
    for topic, items in by_topic.items():
        counts[topic] = len(items)
    missing = {
        "joint_states": int(np.sum(np.isnan(q[:, 0]))),
        "reference": int(np.sum(np.isnan(q_ref[:, 0]))),
        "effort": int(np.sum(np.isnan(tau[:, 0]))),
    }
    return RecordedRun(spec, description, q, qd, q_ref, tau, counts, missing,
                       complete=not any(missing.values()))


def run_samples(run: RecordedRun) -> Samples:
    """Signals of a recorded run at the thesis's analysis instants (complete steps only)."""
    from .simulator import build_samples

    every = run.spec.sample_every
    robot = run.spec.robot_model()
    contour = run.spec.contour_model()
    idx = np.arange(0, run.steps + 1, every)
    ok = ~(np.isnan(run.q[idx, 0]) | np.isnan(run.q_ref[idx, 0]) | np.isnan(run.tau[idx, 0]))
    idx = idx[ok]
    t = idx / run.spec.rate
    return build_samples(run.spec, robot, contour, t, run.q[idx], run.q_ref[idx], run.tau[idx])


def run_metrics(run: RecordedRun) -> Metrics:
    """Thesis statistics of a recorded run, sampled at the thesis's analysis rate."""
    return compute_metrics(run_samples(run), run.spec.bound)
