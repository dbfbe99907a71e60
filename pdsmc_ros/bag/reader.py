"""Reading recorded runs back from rosbag2 MCAP bags (no rclpy needed).

The recorder writes the CDR bytes it received; this module turns a bag into
per-step arrays and a :class:`~pdsmc_ros.runs.builder.RunSpec`, and computes the
thesis statistics with the same code as the in-process simulator. Messages
are read with :mod:`pdsmc_ros.bag.mcapscan` (about 3x faster than a generic MCAP
reader, and it reads a bag whose recorder was killed up to its last complete
chunk) and decoded in bulk with numpy at the byte spans :mod:`pdsmc_ros.bag.cdr`
finds in the first message of each layout; the bags stay standard rosbag2/MCAP
files that rosbags' ``AnyReader``, the ``mcap`` reader and Foxglove open.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import BagError, CdrError
from ..metrics.statistics import Metrics, RunStatistics, Samples, build_samples
from ..robots.base import FloatArray
from ..robots.catalog import ROBOT_DESCRIPTION, register_description
from ..runs.builder import RunSpec, control_steps
from . import cdr
from .stamps import effort_step

DESCRIPTION_KEY = "pdsmc_ros.run_description"
# the recorder's own description of the run, from its parameters, on disk at open: it names a
# run whose controller's description (with its gains) never reached the recorder
RECORDER_DESCRIPTION_TOPIC = "/pdsmc/recorder_description"


def decode_topic(raws: list[bytes], layout_of: Callable[[bytes], dict[str, tuple[int, int]]],
                 ) -> list[tuple[np.ndarray, dict[str, np.ndarray]]]:
    """Decode messages grouped by byte length (a foreign publisher may send other shapes).

    Returns ``(indices into raws, decoded fields)`` per group.
    """
    groups: dict[int, list[int]] = {}
    for i, raw in enumerate(raws):
        groups.setdefault(len(raw), []).append(i)
    out = []
    for indices in groups.values():
        members = [raws[i] for i in indices]
        try:
            layout = layout_of(members[0])
        except CdrError:
            continue  # not a message of the expected kind: skip it
        if any(start + 8 * count > len(members[0]) for start, count in layout.values()):
            continue
        out.append((np.asarray(indices), decode_fixed(members, layout)))
    return out


def decode_fixed(raws: list[bytes], layout: dict[str, tuple[int, int]]) -> dict[str, np.ndarray]:
    """Vectorised decoding of messages that share one byte layout (same length).

    Returns each double field as an ``(len(raws), count)`` array, plus the
    header ``stamp`` in seconds (meaningless for header-less messages).
    """
    size = len(raws[0])
    block = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), size)
    out = {}
    for field, (start, count) in layout.items():
        chunk = np.ascontiguousarray(block[:, start : start + 8 * count])
        out[field] = chunk.view("<f8").reshape(len(raws), count)
    sec = np.ascontiguousarray(block[:, 4:8]).view("<i4")[:, 0]
    nsec = np.ascontiguousarray(block[:, 8:12]).view("<u4")[:, 0]
    out["stamp"] = sec.astype(float) + nsec.astype(float) * 1e-9
    return out


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
    truncated: bool = False
    # steps whose torque is the plant's report, not a recorded command: safe mode, or a command
    # its dying sender got to the plant but not to the recorder
    plant_torque_steps: int = 0
    # the description is the recorder's own (its parameters): the controller's never arrived
    description_from_recorder: bool = False

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
    from .mcapscan import scan

    path = Path(path)
    if not path.exists():
        raise BagError(f"bag {str(path)!r} does not exist")
    files = sorted(path.glob("*.mcap")) if path.is_dir() else [path]
    if not files:
        raise BagError(f"cannot read bag {str(path)!r}: no .mcap file in it")
    topics = ("/pdsmc/run_description", "/joint_states", "/reference", "/effort_controller/commands",
              RECORDER_DESCRIPTION_TOPIC, "/robot_description")
    raw_by_topic: dict[str, list[bytes]] = {t: [] for t in topics}
    truncated = False
    for file in files:
        result = scan(file, topics)
        truncated |= not result.complete
        for topic in topics:
            raw_by_topic[topic] += result.messages[topic]
    own = raw_by_topic.pop(RECORDER_DESCRIPTION_TOPIC)
    from_recorder = not raw_by_topic["/pdsmc/run_description"]
    if from_recorder and not own:
        raise BagError(f"bag {str(path)!r} holds no /pdsmc/run_description: not a pdsmc_ros run")
    described = raw_by_topic.pop("/pdsmc/run_description") or own
    description: dict[str, Any] = json.loads(cdr.decode_string(described[0]))
    urdfs = raw_by_topic.pop("/robot_description")
    if description.get("robot") == ROBOT_DESCRIPTION:
        # the nodes took their arm from /robot_description: so does the analysis, from the bag
        if not urdfs:
            raise BagError(f"bag {str(path)!r}: its run took the arm from /robot_description, which the bag "
                           "does not hold")
        register_description(cdr.decode_string(urdfs[-1]))
    spec = RunSpec.from_description(description)
    n = spec.gains.n
    rate = spec.rate
    steps = control_steps(float(description["duration_s"]), rate)
    q = np.full((steps + 1, n), np.nan)
    qd = np.full((steps + 1, n), np.nan)
    q_ref = np.full((steps + 1, n), np.nan)
    tau = np.full((steps + 1, n), np.nan)
    applied = np.full((steps + 1, n), np.nan)  # torque held over the period ending at k
    counts = {topic: len(items) for topic, items in raw_by_topic.items() if items}
    for _idx, dec in decode_topic(raw_by_topic.get("/joint_states", []), cdr.joint_state_spans):
        if dec["position"].shape[1] < n:
            continue
        k = np.rint(dec["stamp"] * rate).astype(np.int64)
        ok = (k >= 0) & (k <= steps)
        q[k[ok]] = dec["position"][ok, :n]
        qd[k[ok]] = dec["velocity"][ok, :n]
        applied[k[ok]] = dec["effort"][ok, :n]
    for _idx, dec in decode_topic(raw_by_topic.get("/reference", []), cdr.joint_trajectory_spans):
        if dec["positions"].shape[1] != n:
            continue
        k = np.rint(dec["stamp"] * rate).astype(np.int64)
        ok = (k >= 0) & (k <= steps)
        q_ref[k[ok]] = dec["positions"][ok, :n]
    efforts = raw_by_topic.get("/effort_controller/commands", [])
    for idx, dec in decode_topic(efforts, cdr.float64_multi_array_spans):
        # only what the plant would apply: n finite values for a step of this run
        if dec["data"].shape[1] != n:
            continue
        k = np.array([effort_step(efforts[i]) for i in idx], dtype=np.int64)
        ok = (k >= 0) & (k <= steps) & np.all(np.isfinite(dec["data"]), axis=1)
        tau[k[ok]] = dec["data"][ok]
    # the torque actually held over [k, k+1], as the plant reports it with state k + 1
    held = np.vstack([applied[1:], np.full((1, n), np.nan)])
    plant_torque = 0
    if description.get("mode") != "realtime":
        # Lockstep: the plant applies exactly the command of step k (both agree to the bit),
        # except in safe mode, where it held its safe torque instead; what acted on the
        # arm is what the statistics use.
        differs = ~np.isnan(held[:, 0]) & np.any((held != tau) | np.isnan(tau), axis=1)
        plant_torque = int(np.sum(differs))
        tau[differs] = held[differs]
    if description.get("mode") == "realtime":
        # In real time the controller's commands are tagged with the state it last saw and
        # the plant applies whichever is newest at its tick: the torque actually applied
        # over [k, k+1] is the effort the plant reports with state k+1. The reference is
        # recomputed from the run description (the trajectory node publishes the same
        # values, but not necessarily for every plant step).
        tau = held
        tau[-1] = tau[-2]
        q_ref = spec.reference().sample(np.arange(steps + 1) / rate).q
    missing = {
        "joint_states": int(np.sum(np.isnan(q[:, 0]))),
        "reference": int(np.sum(np.isnan(q_ref[:, 0]))),
        "effort": int(np.sum(np.isnan(tau[:, 0]))),
    }
    return RecordedRun(spec, description, q, qd, q_ref, tau, counts, missing,
                       complete=not any(missing.values()) and not truncated, truncated=truncated,
                       plant_torque_steps=plant_torque, description_from_recorder=from_recorder)


def run_samples(run: RecordedRun) -> Samples:
    """Signals of a recorded run at the thesis's analysis instants (complete steps only)."""
    every = run.spec.sample_every
    robot = run.spec.robot_model()
    contour = run.spec.contour_model()
    idx = np.arange(0, run.steps + 1, every)
    ok = ~(np.isnan(run.q[idx, 0]) | np.isnan(run.q_ref[idx, 0]) | np.isnan(run.tau[idx, 0]))
    idx = idx[ok]
    t = idx / run.spec.rate
    return build_samples(robot, contour, t, run.q[idx], run.q_ref[idx], run.tau[idx])


def run_metrics(run: RecordedRun) -> Metrics:
    """Thesis statistics of a recorded run, sampled at the thesis's analysis rate, and the scores
    of its control steps as the simulator computes them (none if a step is missing: they need
    every period)."""
    samples = run_samples(run)
    stats = RunStatistics(run.q.shape[1], bound=run.spec.bound, rate=run.spec.rate)
    stats.add_samples(samples)
    if len(run.q) >= 2 and not (np.isnan(run.q).any() or np.isnan(run.q_ref).any() or np.isnan(run.tau).any()):
        stats.add_steps(run.q_ref - run.q, run.tau)
    return stats.metrics()
