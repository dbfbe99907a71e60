"""Message types found in a ROS graph: their Python classes and their definitions for a bag.

``ros2 bag record`` takes a topic's type from the graph (``get_topic_names_and_types``) and
its definition from the ``.msg``/``.idl`` files of the installed packages. The recorder does the
same from the type's generated Python class, which every importable type has -- including the
types rosidl derives from an action (``pkg/action/Name_FeedbackMessage``) and from a service
(``pkg/srv/Name_Event``), which have no file of their own: :func:`message_class` finds the
class, :func:`register_type` writes its fields (recursively) into a rosbags typestore, which
gives the bag's ``ros2msg`` definition. Constants are left out: a reader needs the fields only.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any

from rosbags.typesys import get_types_from_msg
from rosbags.typesys.store import Typestore
from rosidl_parser import definition

from ..errors import ConfigError

_BASIC = {"boolean": "bool", "octet": "byte", "float": "float32", "double": "float64", "char": "char"}


def message_class(type_name: str) -> Any:
    """The Python class of ``pkg/msg/Name`` (or ``pkg/action/Name_FeedbackMessage``, ``pkg/srv/Name_Event``...).

    Raises
    ------
    ConfigError
        If the type's package is not installed or holds no such message type.
    """
    found = interface_class(type_name)
    if not hasattr(found, "SLOT_TYPES"):
        raise ConfigError(f"{type_name!r} is not a message type")
    return found


def interface_class(type_name: str) -> Any:
    """The Python class of a message, service or action type ``pkg/kind/Name`` (see :func:`message_class`).

    Raises
    ------
    ConfigError
        If the type's package is not installed or holds no such type.
    """
    parts = type_name.split("/")
    if len(parts) != 3 or not all(parts):
        raise ConfigError(f"message type {type_name!r} is not of the form package/msg/Name")
    package, kind, name = parts
    try:
        module = importlib.import_module(f"{package}.{kind}")
    except ImportError:
        raise ConfigError(f"message type {type_name!r}: package {package!r} is not installed") from None
    found = getattr(module, name, None)
    if found is None and "_" in name:
        # a type rosidl derived from an action or a service lives in the module of its parent
        parent = getattr(module, name.split("_", 1)[0], None)
        found = getattr(sys.modules.get(getattr(parent, "__module__", ""), None), name, None)
    if found is None:
        raise ConfigError(f"message type {type_name!r} is not in the installed {package!r}")
    return found


def _namespaced(value: definition.NamespacedType) -> str:
    return "/".join([*value.namespaces, value.name])


def _field_type(value: Any, needed: list[str]) -> str:
    """The ``.msg`` spelling of a rosidl field type; the message types it names go to ``needed``."""
    if isinstance(value, definition.Array):
        return f"{_field_type(value.value_type, needed)}[{value.size}]"
    if isinstance(value, definition.BoundedSequence):
        return f"{_field_type(value.value_type, needed)}[<={value.maximum_size}]"
    if isinstance(value, definition.UnboundedSequence):
        return f"{_field_type(value.value_type, needed)}[]"
    if isinstance(value, definition.BoundedString):
        return f"string<={value.maximum_size}"
    if isinstance(value, definition.UnboundedString):
        return "string"
    if isinstance(value, definition.BoundedWString):
        return f"wstring<={value.maximum_size}"
    if isinstance(value, definition.UnboundedWString):
        return "wstring"
    if isinstance(value, definition.NamespacedType):
        name = _namespaced(value)
        needed.append(name)
        return name
    if isinstance(value, definition.BasicType):
        return _BASIC.get(value.typename, value.typename)
    raise ConfigError(f"field type {value!r} has no .msg spelling")


def _fields_text(type_name: str) -> tuple[str, list[str]]:
    """The ``.msg`` text of a type's fields, and the message types they name (in order)."""
    cls = message_class(type_name)
    needed: list[str] = []
    lines = [f"{_field_type(slot, needed)} {field}"
             for slot, field in zip(cls.SLOT_TYPES, cls.get_fields_and_field_types(), strict=True)]
    return "\n".join(lines) + "\n", needed


def type_definition(typestore: Typestore, type_name: str) -> tuple[str, str]:
    """``type_name``'s definition as rosbag2 writes it (``ros2msg``: the type's fields, then each
    type it uses after a line of ``=`` and ``MSG: pkg/kind/Name``) and its RIHS01 hash; the types
    are added to ``typestore`` (those it lacks), so that it can read the messages.

    Raises
    ------
    ConfigError
        If a type cannot be found (:func:`message_class`).
    """
    texts: dict[str, str] = {}
    pending = [type_name]
    while pending:
        name = pending.pop(0)
        if name in texts:
            continue
        texts[name], needed = _fields_text(name)
        pending += needed
    missing: dict[str, Any] = {}
    for name, text in texts.items():
        if name in typestore.fielddefs and "/msg/" in name:
            # a message type the store knows: its own text (with its constants), so the hash a reader
            # computes from this definition is the store's (rosbags writes texts of /msg/ types only)
            texts[name] = typestore.generate_msgdef(name, ros_version=2)[0].split("\n" + "=" * 80)[0]
        elif name not in typestore.fielddefs:
            missing.update(get_types_from_msg(text, name))
    if missing:
        typestore.register(missing)
    parts = [texts[type_name]]
    parts += [f"{'=' * 80}\nMSG: {name}\n{text}" for name, text in texts.items() if name != type_name]
    return "\n".join(parts), typestore.hash_rihs01(type_name)
