"""The identified arm as files every command takes: a corrected URDF and the options beside it.

``<out>/identified.urdf`` is the arm's URDF with each moving link's ``<inertial>`` replaced by
the identified body (mass, centre of mass, inertia about it, in the link's frame: URDF's child
link of a joint has the joint's frame, where Pinocchio's regressor expresses its body) and its
joints' ``<dynamics>`` zeroed; links fixed to a moving link (Pinocchio merges them into its body,
so the identification sees their sum) lose their ``<inertial>``. ``<out>/identified.yaml`` is its
options file (:mod:`pdsmc_ros.robots.catalog` reads ``arm.yaml`` beside ``arm.urdf``): the
arm's own options and run settings, and the identified ``armature``, ``friction_coulomb``,
``friction_viscous`` (the joints' whole viscous friction: the URDF's damping is zero),
``payload_mass`` and ``payload_com`` (a point mass in the end-effector frame; what rotational
inertia the payload has about its centre is added to the end-effector's link in the URDF). So
``--robot <out>/identified.urdf`` -- or ``--model <out>/identified.yaml`` for the laws' model
alone -- is the identified arm, and its model is the identified parameters exactly
(test/identification).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any
from xml.etree import ElementTree

import numpy as np
import yaml

from ..robots.base import FloatArray
from .model import ArmDynamics

__all__ = ["URDF_NAME", "OPTIONS_NAME", "corrected_urdf", "identified_options"]

URDF_NAME = "identified.urdf"
OPTIONS_NAME = "identified.yaml"
"""The file names in the output directory (the catalog pairs ``X.urdf`` with ``X.yaml``)."""


def _body(ten: FloatArray) -> tuple[float, FloatArray, FloatArray]:
    """Mass, centre of mass and inertia about it of ten parameters (a body: mass > 0)."""
    m = float(ten[0])
    c = np.asarray(ten[1:4]) / m
    about_origin = np.array([[ten[4], ten[5], ten[7]], [ten[5], ten[6], ten[8]], [ten[7], ten[8], ten[9]]])
    shift = m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    return m, c, about_origin - shift


def _point_mass(m: float, c: FloatArray) -> FloatArray:
    if m <= 0.0:
        return np.zeros(10)
    inertia = m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    return np.array([m, *(m * c), inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2],
                     inertia[2, 2]])


def payload_point(dynamics: ArmDynamics, values: FloatArray) -> tuple[float, FloatArray]:
    """The payload's mass (kg) and centre of mass (m, end-effector frame) of ``values``."""
    ten = values[dynamics.layout.payload]
    m = float(ten[0])
    return (m, np.asarray(ten[1:4]) / m) if m > 0.0 else (0.0, np.zeros(3))


def _fmt(x: float) -> str:
    return f"{x:.9g}"


def corrected_urdf(dynamics: ArmDynamics, values: FloatArray, *, note: str = "") -> str:
    """The arm's URDF with ``values``' bodies (module docstring); ``note`` goes in a comment."""
    arm = dynamics.arm
    root = ElementTree.fromstring(arm.urdf)
    for element in root.findall("pdsmc_ros"):
        root.remove(element)
    joints = {j.get("name"): j for j in root.findall("joint")}
    links = {link.get("name"): link for link in root.findall("link")}
    children: dict[str, list[Any]] = {}
    for joint in joints.values():
        parent = joint.find("parent")
        if parent is not None:
            children.setdefault(parent.get("link", ""), []).append(joint)
    moving = set(arm.joint_names)
    layout = dynamics.layout
    mass, com = payload_point(dynamics, values)
    for i, name in enumerate(arm.joint_names):
        ten = values[layout.link(i)].copy()
        if i == dynamics.payload_joint:  # the payload's own rotational inertia, on its link
            ten += dynamics.payload_to_body @ (values[layout.payload] - _point_mass(mass, com))
        link = links[layout.bodies[i]]
        _set_inertial(link, ten)
        dynamics_element = joints[name].find("dynamics")
        if dynamics_element is not None:
            dynamics_element.set("damping", "0")
            dynamics_element.set("friction", "0")
        # the links fixed below it were merged into its body: their mass is in ten already
        stack = list(children.get(layout.bodies[i], []))
        while stack:
            joint = stack.pop()
            if joint.get("name") in moving:
                continue
            child = links.get(joint.find("child").get("link"))
            if child is None:
                continue
            for inertial in child.findall("inertial"):
                child.remove(inertial)
            stack.extend(children.get(child.get("name", ""), []))
    text = ElementTree.tostring(root, encoding="unicode")
    comment = ("<!-- identified by pdsmc_ros (pdsmc identify): each moving link's inertial is the identified "
               "body, with the links fixed to it merged in; joint friction, motor inertia and the payload are "
               f"in {OPTIONS_NAME} beside this file.{(' ' + note) if note else ''} -->")
    return f'<?xml version="1.0"?>\n{comment}\n{text}\n'


def _set_inertial(link: Any, ten: FloatArray) -> None:
    m, c, inertia = _body(ten)
    for inertial in link.findall("inertial"):
        link.remove(inertial)
    inertial = ElementTree.SubElement(link, "inertial")
    ElementTree.SubElement(inertial, "origin", xyz=" ".join(_fmt(v) for v in c), rpy="0 0 0")
    ElementTree.SubElement(inertial, "mass", value=_fmt(m))
    ElementTree.SubElement(inertial, "inertia", ixx=_fmt(inertia[0, 0]), ixy=_fmt(inertia[0, 1]),
                           ixz=_fmt(inertia[0, 2]), iyy=_fmt(inertia[1, 1]), iyz=_fmt(inertia[1, 2]),
                           izz=_fmt(inertia[2, 2]))


def identified_options(dynamics: ArmDynamics, values: FloatArray) -> dict[str, Any]:
    """The options file of the identified arm: the arm's own options and run settings with the
    identified joint parameters and payload (module docstring)."""
    arm = dynamics.arm
    layout = dynamics.layout
    mass, com = payload_point(dynamics, values)
    options: dict[str, Any] = {
        k: v for k, v in arm.options.items()
        if k not in ("armature", "friction_coulomb", "friction_viscous", "payload_mass", "payload_com")}
    options.update({
        "effort_limits": arm.effort_limits.tolist(),
        "velocity_limits": arm.velocity_limits.tolist(),
        "position_limits": arm.position_limits.tolist(),
        "armature": _rounded(values[layout.joint_field("armature")]),
        "friction_coulomb": _rounded(values[layout.joint_field("friction_coulomb")]),
        "friction_viscous": _rounded(values[layout.joint_field("friction_viscous")]),
        "payload_mass": float(f"{mass:.9g}"),
        "payload_com": _rounded(com),
    })
    settings: Mapping[str, Any] = arm.settings
    options.update({k: v for k, v in settings.items() if k != "gains"})
    gains = settings.get("gains", arm.name)
    if isinstance(gains, dict) or (isinstance(gains, str) and not gains.lower().endswith(".urdf")):
        options["gains"] = gains  # the arm's preset gains carry over (a path names no table)
    if options.get("locked_joints") == []:
        options.pop("locked_joints")
    return options


def _rounded(values: FloatArray) -> list[float]:
    return [float(f"{v:.9g}") for v in np.asarray(values, dtype=float)]


def options_text(options: Mapping[str, Any], header: str) -> str:
    """The options as YAML, after a comment ``header``."""
    lines = "".join(f"# {line}\n" for line in header.splitlines())
    return lines + str(yaml.safe_dump(dict(options), sort_keys=False, default_flow_style=None, width=120))
