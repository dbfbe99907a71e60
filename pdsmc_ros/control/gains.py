"""Gains: the diagonal control parameters of a law, validated."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError
from .registry import GAIN_NAMES, law


@dataclass(frozen=True)
class Gains:
    """Diagonal control parameters per actuated joint (unused ones zero, phi one)."""

    kp: tuple[float, ...]
    kd: tuple[float, ...]
    ks: tuple[float, ...]
    lam: tuple[float, ...]
    phi: tuple[float, ...]

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], n: int, controller: str) -> Gains:
        """Build from a ``{kp: [...], ...}`` mapping, validating names, lengths and signs."""
        unknown = set(data) - set(GAIN_NAMES)
        if unknown:
            raise ConfigError(
                f"unknown gain(s) {sorted(unknown)} for {controller}; allowed: {', '.join(GAIN_NAMES)}"
            )
        missing = [g for g in law(controller).gains if g not in data]
        if missing:
            raise ConfigError(f"{controller} needs gains {', '.join(missing)}")
        values: dict[str, tuple[float, ...]] = {}
        for name in GAIN_NAMES:
            default = 1.0 if name == "phi" else 0.0
            raw = data.get(name, [default] * n)
            try:
                arr = np.asarray(raw, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                raise ConfigError(f"gain {name} must be a list of {n} numbers, got {raw!r}") from None
            if arr.size == 1:
                arr = np.full(n, arr[0])
            if arr.size != n:
                raise ConfigError(f"gain {name} needs {n} values (one per joint), got {arr.size}")
            if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
                raise ConfigError(f"gain {name} must be finite and >= 0, got {arr.tolist()}")
            if name == "phi" and np.any(arr <= 0.0):
                raise ConfigError(f"boundary layer phi must be > 0, got {arr.tolist()}")
            values[name] = tuple(float(v) for v in arr)
        return cls(**values)

    def scaled(self, factors: Mapping[str, float]) -> Gains:
        """Gains with some parameters multiplied (Section 4.5.3)."""
        changes = {
            name: tuple(v * float(factor) for v in getattr(self, name))
            for name, factor in factors.items()
        }
        return dataclasses.replace(self, **changes)

    def matrix(self) -> np.ndarray:
        """``(5, n)`` array with rows kp, kd, ks, lam, phi (:attr:`LawSetup.gains`)."""
        return np.array([self.kp, self.kd, self.ks, self.lam, self.phi], dtype=float)

    def as_dict(self) -> dict[str, list[float]]:
        return {name: list(getattr(self, name)) for name in GAIN_NAMES}
