"""Benchmark: what the live viewer costs the lockstep loop, and what a Foxglove client receives.

Runs the serial circle in lockstep (four nodes, or composed intra-process) through
scripts/run_experiment.sh without and with ``--viewer``, in alternating rounds (this machine's
speed drifts), a Foxglove WebSocket client connected during the viewed runs. Prints steps per
second of each (bench/lockstep.py's measure) and the client's messages per second per channel.

Last line: ``viewer_cost_pct=P frames_per_s=F`` (median steps/s with the viewer against without,
composed intra-process; /tf frames per second the client received).

Usage: python bench/viewer.py [--rounds 3] [--steps 20000]   (inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import socket
import statistics
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lockstep import lockstep_steps_per_s  # noqa: E402


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def client(port: int, seconds: float, counts: dict[str, int]) -> None:
    """Connect, subscribe to every channel, count messages for ``seconds`` after the first one."""
    import websockets

    async def run() -> None:
        deadline = time.monotonic() + 120
        while True:
            try:
                ws = await websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"])
                break
            except OSError:
                if time.monotonic() > deadline:
                    return
                await asyncio.sleep(0.1)
        async with ws:
            channels: dict[int, str] = {}
            while len(channels) < 4:
                message = json.loads(await ws.recv())
                if message["op"] == "advertise":
                    channels.update({c["id"]: c["topic"] for c in message["channels"]})
            ids = list(channels)
            await ws.send(json.dumps({"op": "subscribe",
                                      "subscriptions": [{"id": i, "channelId": c} for i, c in enumerate(ids)]}))
            start = None
            while start is None or time.monotonic() - start < seconds:
                try:
                    message = await asyncio.wait_for(ws.recv(), 5)
                except (asyncio.TimeoutError, websockets.ConnectionClosed):
                    break
                if isinstance(message, bytes) and message[0] == 1:
                    start = start or time.monotonic()
                    topic = channels[ids[int.from_bytes(message[1:5], "little")]]
                    counts[topic] = counts.get(topic, 0) + 1
            counts["seconds"] = time.monotonic() - (start or time.monotonic())

    asyncio.run(run())


def viewed_run(steps: int, composition: list[str]) -> tuple[float, dict[str, int]]:
    port = free_port()
    counts: dict[str, int] = {}
    watcher = threading.Thread(target=client, args=(port, 3.0, counts), daemon=True)
    watcher.start()
    rate, _ = lockstep_steps_per_s(steps, [*composition, "--viewer", "--viewer-port", str(port)])
    watcher.join(timeout=30)
    return rate, counts


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--steps", type=int, default=20000)
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", "91")
    results: dict[str, dict[str, list[float]]] = {}
    frames = []
    for label, composition in (("4 processes", []), ("composed intra-process", ["--composed", "--intra-process"])):
        plain, viewed = [], []
        for _ in range(args.rounds):
            plain.append(lockstep_steps_per_s(args.steps, composition)[0])
            rate, counts = viewed_run(args.steps, composition)
            viewed.append(rate)
            if counts.get("seconds"):
                per_s = {k: v / counts["seconds"] for k, v in counts.items() if k != "seconds"}
                frames.append(per_s.get("/tf", 0.0))
                print("  client: " + ", ".join(f"{k} {v:.1f}/s" for k, v in sorted(per_s.items())), flush=True)
        results[label] = {"without": plain, "with": viewed}
        print(f"{label}: without viewer {statistics.median(plain):,.0f} steps/s {[round(x) for x in plain]}, "
              f"with viewer {statistics.median(viewed):,.0f} {[round(x) for x in viewed]}", flush=True)
    composed = results["composed intra-process"]
    cost = 100.0 * (1.0 - statistics.median(composed["with"]) / statistics.median(composed["without"]))
    print(f"viewer_cost_pct={cost:.1f} frames_per_s={statistics.median(frames) if frames else float('nan'):.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
