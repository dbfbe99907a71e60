"""The live viewer (issue 17): what it shows, and a real Foxglove WebSocket client during a run."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import socket
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from pdsmc_ros.bag.reader import read_run
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate
from pdsmc_ros.viewer.live_view import CHANNELS, LiveView

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "run_experiment.sh"


def test_a_frame_is_the_newest_state_with_its_errors() -> None:
    spec = make_run("serial_3r", "circle", "pdsmc")
    view = LiveView(spec)
    assert view.frame() is None  # nothing received yet
    ref = spec.reference().sample(np.array([0.1])).q[0]
    q = ref + np.array([1e-3, -2e-3, 0.0])
    view.add_state(0, 100_000_000, ["joint1", "joint2", "joint3"], q.tolist())
    view.add_effort([1.0, 2.0, 3.0])
    frame = view.frame()
    assert frame is not None and frame.step == 1000 and frame.sim_time == pytest.approx(0.1)
    np.testing.assert_allclose(frame.joint_error, ref - q, rtol=0, atol=1e-15)
    xy = spec.robot_model().position(q)
    assert frame.contour_error == spec.contour_model().contour_error(np.array([0.1]), xy[None])[0]
    np.testing.assert_allclose(frame.actual, [xy[0], 0.0, xy[1]])  # the URDF's x-z plane
    assert frame.torque == [1.0, 2.0, 3.0]
    assert [t.child for t in frame.transforms] == ["tool0", "link1", "link2", "link3"]
    assert view.frame() is None  # the same state is not shown twice


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


async def watch(port: int, seconds: float) -> tuple[dict, dict, dict | None]:
    """A Foxglove WebSocket client: channels advertised, messages received per topic, the last errors."""
    import websockets

    deadline = time.monotonic() + 120
    while True:
        try:
            ws = await websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"])
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.2)
    async with ws:
        channels: dict[int, dict] = {}
        while len(channels) < len(CHANNELS):
            message = json.loads(await asyncio.wait_for(ws.recv(), 30))
            if message["op"] == "advertise":
                channels.update({c["id"]: c for c in message["channels"]})
        ids = list(channels)
        await ws.send(json.dumps({"op": "subscribe",
                                  "subscriptions": [{"id": i, "channelId": c} for i, c in enumerate(ids)]}))
        counts: dict[str, int] = {}
        errors = None
        # ``seconds`` from the first frame: the viewer serves before the run starts (the nodes warm
        # their kernels up first), and a client may connect long before a frame
        first_frame_by = time.monotonic() + 120
        start: float | None = None
        while start is None or time.monotonic() - start < seconds:
            wait = seconds if start is not None else max(first_frame_by - time.monotonic(), 0.0)
            try:
                message = await asyncio.wait_for(ws.recv(), wait)
            except (asyncio.TimeoutError, websockets.ConnectionClosed):
                break
            if isinstance(message, bytes) and message[0] == 1:  # messageData: subscription, log time, payload
                if start is None:
                    start = time.monotonic()
                topic = channels[ids[int.from_bytes(message[1:5], "little")]]["topic"]
                counts[topic] = counts.get(topic, 0) + 1
                if topic == "/pdsmc/errors":
                    errors = json.loads(message[13:])
        return {c["topic"]: (c["schemaName"], c["encoding"]) for c in channels.values()}, counts, errors


@pytest.mark.timeout(300)
def test_a_foxglove_client_watches_a_lockstep_run_that_stays_the_same(ros_env: dict, tmp_path: Path) -> None:
    pytest.importorskip("websockets")
    port = free_port()
    out = tmp_path / "viewed"
    proc = subprocess.Popen(["bash", str(SCRIPT), "--robot", "serial_3r", "--contour", "circle", "--controller",
                             "pdsmc", "--duration-factor", "0.6", "--out", str(out), "--timeout", "250",
                             "--viewer", "--viewer-port", str(port)],
                            env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        channels, counts, errors = asyncio.run(watch(port, 2.0))
        _, stderr = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 0, stderr
    assert channels == {"/tf": ("foxglove.FrameTransforms", "protobuf"),
                        "/robot_description": ("std_msgs/msg/String", "json"),
                        "/end_effector/paths": ("foxglove.SceneUpdate", "protobuf"),
                        "/pdsmc/errors": ("pdsmc_ros/Errors", "json")}
    assert counts.get("/tf", 0) >= 5 and counts.get("/pdsmc/errors", 0) >= 5, counts
    assert errors is not None and 0.0 <= errors["contour_error"] < 1e-3 and len(errors["joint_error"]) == 3
    assert max(abs(e) for e in errors["joint_error"]) < 1e-2
    # an observer: the recorded run is still exactly the in-process one
    run = read_run(out)
    assert run.complete
    sim = simulate(run.spec)
    assert np.max(np.abs(run.q[:: run.spec.sample_every] - sim.samples.q)) <= 1e-9
    log = (Path(f"{out}.logs") / "viewer.log").read_text()
    assert f"ws://127.0.0.1:{port}" in log and "the plant has left" in log


def test_bad_viewer_parameters_are_one_line(ros_env: dict) -> None:
    proc = subprocess.run(["ros2", "run", "pdsmc_ros", "viewer", "--ros-args", "-p", "display_rate:=0.0"],
                          env=ros_env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "viewer: error: parameter display_rate must be a number > 0 and <= 240, got 0.0"]
