"""Real-time processes write asynchronously and over UDP only (pdsmc_ros/loop/process.py
choose_middleware): the mode each node is given, read before rclpy starts as rcl will resolve it,
chooses; the environment's own choices are kept. bench/storm/ measures why (a synchronous write
stood the loop still 13-22 ms while clients subscribed, a shared-memory port's health check 333 ms)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

pytest.importorskip("rclpy")

from pdsmc_ros.loop.process import (  # noqa: E402
    BUILTIN_TRANSPORTS,
    DISCOVERY_RANGE,
    PROFILES_FILE,
    PUBLICATION_MODE,
    TRANSPORTS_CHOSEN_BY,
    choose_middleware,
)
from pdsmc_ros.parameters.params_file import given_value  # noqa: E402
from pdsmc_ros.resources import config_dir  # noqa: E402

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


def test_real_time_writes_asynchronously_over_udp_unless_the_environment_chooses(
        monkeypatch: pytest.MonkeyPatch) -> None:
    for key in (PUBLICATION_MODE, DISCOVERY_RANGE, "RMW_IMPLEMENTATION", "ROS_STATIC_PEERS", *TRANSPORTS_CHOSEN_BY):
        monkeypatch.delenv(key, raising=False)
    realtime = ["--ros-args", "-p", "mode:=realtime"]

    def chosen(names: list[str], args: list[str], **environment: str) -> dict[str, str]:
        outside = dict(os.environ)
        os.environ.update(environment)
        before = dict(os.environ)
        try:
            made = choose_middleware(names, args)
            assert os.environ == {**before, **made}  # what it returns is what it set, and nothing else
        finally:
            os.environ.clear()
            os.environ.update(outside)
        return made

    assert chosen(["controller"], ["--ros-args", "-p", "mode:=lockstep"]) == {}
    udp = {PUBLICATION_MODE: "ASYNCHRONOUS", BUILTIN_TRANSPORTS: "UDPv4"}
    assert chosen(["controller"], realtime) == udp  # Jazzy's default range, SUBNET
    assert chosen(["mujoco_driver"], [], **{DISCOVERY_RANGE: "SUBNET"}) == udp  # real time whatever it is given
    assert chosen(["controller"], realtime, **{DISCOVERY_RANGE: "SYSTEM_DEFAULT"}) == udp
    localhost = chosen(["controller"], realtime, **{DISCOVERY_RANGE: "LOCALHOST"})
    assert localhost.pop(PROFILES_FILE).endswith("config/fastdds_realtime_localhost.xml")
    assert localhost == {PUBLICATION_MODE: "ASYNCHRONOUS", DISCOVERY_RANGE: "SYSTEM_DEFAULT"}
    writes_only = {PUBLICATION_MODE: "ASYNCHRONOUS"}  # the transports as the environment has them
    assert chosen(["controller"], realtime, **{DISCOVERY_RANGE: "OFF"}) == writes_only
    peers = {DISCOVERY_RANGE: "LOCALHOST", "ROS_STATIC_PEERS": "10.0.0.2"}  # other hosts too
    assert chosen(["controller"], realtime, **peers) == writes_only
    assert chosen(["controller"], realtime, RMW_IMPLEMENTATION="rmw_cyclonedds_cpp") == writes_only
    for key in TRANSPORTS_CHOSEN_BY:
        assert chosen(["controller"], realtime, **{key: "1", DISCOVERY_RANGE: "LOCALHOST"}) == writes_only, key
    assert chosen(["controller"], realtime, ROS_LOCALHOST_ONLY="1") == writes_only  # rcl: LOCALHOST, rmw's
    assert chosen(["controller"], realtime, ROS_LOCALHOST_ONLY="0") == udp  # rcl: the range decides
    assert chosen(["controller"], realtime, **{PUBLICATION_MODE: "SYNCHRONOUS"}) == {BUILTIN_TRANSPORTS: "UDPv4"}
    assert chosen(["controller"], realtime, **{PUBLICATION_MODE: ""}) == udp  # empty: rmw's default, unchosen
    # scripts/run_experiment.sh's own profile (leases, heartbeats) sets no transports: UDP beside it under
    # SUBNET; under LOCALHOST the real-time profile would drop its settings, so shared memory stays
    own = {PROFILES_FILE: str(config_dir() / "fastdds_profile.xml")}  # where run_experiment.sh finds it
    assert chosen(["controller"], realtime, **own) == udp
    assert chosen(["controller"], realtime, **own, **{DISCOVERY_RANGE: "LOCALHOST"}) == writes_only


def test_the_real_time_localhost_profile_is_valid_fast_dds_xml() -> None:
    """The profile rmw_fastrtps reads in a real-time process under LOCALHOST: UDP on the loopback
    only, the participant's default (a profile Fast DDS cannot parse is ignored with one log line)."""
    import xml.etree.ElementTree as ElementTree

    ns = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    root = ElementTree.parse(ROOT / "config" / "fastdds_realtime_localhost.xml").getroot()
    (transport,) = root.findall("p:transport_descriptors/p:transport_descriptor", ns)
    assert transport.findtext("p:type", namespaces=ns) == "UDPv4"
    assert transport.findtext("p:interfaceWhiteList/p:address", namespaces=ns) == "127.0.0.1"
    (participant,) = root.findall("p:participant", ns)
    assert participant.get("is_default_profile") == "true"
    assert participant.findtext("p:rtps/p:useBuiltinTransports", namespaces=ns) == "false"
    assert participant.findtext("p:rtps/p:userTransports/p:transport_id", namespaces=ns) == transport.findtext(
        "p:transport_id", namespaces=ns)
