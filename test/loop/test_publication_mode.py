"""Real-time processes write asynchronously (pdsmc_ros/loop/process.py choose_publication_mode): the
mode each node is given, read before rclpy starts as rcl will resolve it, chooses; the environment's
own choice is kept. bench/storm.py measures why (a synchronous write stood the loop still 13-333 ms
while clients subscribed)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

pytest.importorskip("rclpy")

from pdsmc_ros.loop.process import PUBLICATION_MODE, choose_publication_mode  # noqa: E402
from pdsmc_ros.settings import given_value  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def test_the_mode_given_is_read_as_rcl_resolves_it(tmp_path: Path) -> None:
    params = tmp_path / "p.yaml"
    params.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"mode": "realtime"}},
                                      "plant": {"ros__parameters": {"mode": "lockstep"}}}))
    files = ["--ros-args", "--params-file", str(params)]
    assert given_value("mode", "/controller", files) == "realtime"  # the /** section
    assert given_value("mode", "/plant", files) == "lockstep"  # its own section, later in the file
    assert given_value("mode", "/controller", [*files, "-p", "mode:=lockstep"]) == "lockstep"  # -p last
    assert given_value("mode", "/controller", ["--ros-args", "-p", "plant:mode:=realtime"]) is None
    assert given_value("mode", "/controller", ["--ros-args", "-p", "controller:mode:=realtime"]) == "realtime"
    shipped = ["--ros-args", "--params-file", str(ROOT / "config" / "pdsmc_params.yaml")]
    assert given_value("mode", "/controller", shipped) == "lockstep"
    assert given_value("mode", "/controller", ["--ros-args", "--params-file", str(tmp_path / "none.yaml")]) is None


def test_real_time_writes_asynchronously_unless_the_environment_chooses(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(PUBLICATION_MODE, raising=False)
    assert choose_publication_mode(["controller"], ["--ros-args", "-p", "mode:=lockstep"]) is None
    assert PUBLICATION_MODE not in os.environ
    assert choose_publication_mode(["controller"], ["--ros-args", "-p", "mode:=realtime"]) == "ASYNCHRONOUS"
    assert os.environ[PUBLICATION_MODE] == "ASYNCHRONOUS"
    monkeypatch.delenv(PUBLICATION_MODE)
    assert choose_publication_mode(["mujoco_driver"], []) == "ASYNCHRONOUS"  # real time whatever it is given
    monkeypatch.setenv(PUBLICATION_MODE, "SYNCHRONOUS")
    assert choose_publication_mode(["controller"], ["--ros-args", "-p", "mode:=realtime"]) is None
    assert os.environ[PUBLICATION_MODE] == "SYNCHRONOUS"
