"""The one place that finds and reads ``config/`` (package data; no ROS environment needed)."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import yaml

from .errors import ConfigError
from .resources import config_dir


@functools.lru_cache(maxsize=16)
def _load_yaml(path: str) -> Any:
    try:
        with open(path, encoding="utf-8") as handle:
            return yaml.safe_load(handle)
    except OSError as exc:
        raise ConfigError(f"cannot read {path}: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path} is not valid YAML: {exc}") from exc


def read_yaml(path: str | Path, label: str) -> Any:
    """A user's YAML file (uncached): its data, or one ConfigError line starting with ``label``."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{label}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{label}: not YAML ({str(exc).splitlines()[0]})") from None


def load_config(name: str, directory: Path | None = None) -> Any:
    """Parsed ``config/<name>.yaml`` (cached; treat it as read-only)."""
    return _load_yaml(str((directory or config_dir()) / f"{name}.yaml"))


def choice(value: str, allowed: tuple[str, ...] | list[str], what: str) -> str:
    """``value`` if it is one of ``allowed``; a ConfigError listing them otherwise."""
    if value not in allowed:
        raise ConfigError(f"unknown {what} {value!r}; choose one of: {', '.join(allowed)}")
    return value
