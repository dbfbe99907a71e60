"""Gains: the control parameters of one law, validated against its declaration."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError
from .registry import law


@dataclass(frozen=True)
class Gains(Mapping[str, tuple[float, ...]]):
    """A law's gains by name, in the order of its gain matrix's rows (:attr:`LawEntry.rows`).

    A per-joint gain holds ``n`` values, a scalar one value. Read one as ``gains["kp"]``.

    Attributes
    ----------
    n : int
        Joints.
    rows : tuple of (str, tuple of float)
        Each row's gain name and values.
    """

    n: int
    rows: tuple[tuple[str, tuple[float, ...]], ...]

    def __getitem__(self, name: str) -> tuple[float, ...]:
        for key, values in self.rows:
            if key == name:
                return values
        raise KeyError(name)

    def __iter__(self) -> Iterator[str]:
        return (key for key, _ in self.rows)

    def __len__(self) -> int:
        return len(self.rows)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], n: int, controller: str, *, partial: bool = False) -> Gains:
        """Build from a ``{kp: [...], ...}`` mapping, validated against ``controller``'s declaration.

        Names must be rows of the law, every gain it needs must be given, a per-joint gain needs
        ``n`` values (one value stands for all), a scalar one value, each within its bounds.
        Rows not given hold their neutral value (``partial``: needed ones too, to check one layer
        of a run's gains on its own).
        """
        entry = law(controller)
        names = [spec.name for spec in entry.row_specs]
        unknown = set(data) - set(names)
        if unknown:
            raise ConfigError(f"unknown gain(s) {sorted(unknown)} for {controller}; allowed: {', '.join(names)}")
        missing = [] if partial else [g for g in entry.gain_names if g not in data]
        if missing:
            raise ConfigError(f"{controller} needs gains {', '.join(missing)}")
        rows = []
        for spec in entry.row_specs:
            size = n if spec.per_joint else 1
            raw = data.get(spec.name, [spec.neutral] * size)
            what = f"{n} values (one per joint)" if spec.per_joint else "one value (for every joint)"
            try:
                arr = np.asarray(raw, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                raise ConfigError(f"gain {spec.name} must be numbers, {what}, got {raw!r}") from None
            if arr.size == 1:
                arr = np.full(size, arr[0])
            if arr.size != size:
                raise ConfigError(f"gain {spec.name} needs {what}, got {arr.size}")
            spec.check(arr, controller)
            rows.append((spec.name, tuple(float(v) for v in arr)))
        return cls(n, tuple(rows))

    def scaled(self, factors: Mapping[str, float]) -> Gains:
        """Gains with some multiplied (Section 4.5.3): ``factors`` by gain name."""
        return Gains(self.n, tuple(
            (key, tuple(v * float(factors[key]) for v in values) if key in factors else values)
            for key, values in self.rows
        ))

    def replaced(self, changes: Mapping[str, Any], controller: str) -> Gains:
        """These gains with some given anew, validated as :meth:`from_mapping` validates."""
        return Gains.from_mapping({**self.as_dict(), **changes}, self.n, controller)

    def matrix(self) -> np.ndarray:
        """``(rows, n)`` array (:attr:`LawSetup.gains`); a scalar gain fills its row."""
        return np.array([np.broadcast_to(np.asarray(values, dtype=float), (self.n,)) for _, values in self.rows],
                        dtype=float)

    def as_dict(self) -> dict[str, list[float]]:
        return {key: list(values) for key, values in self.rows}
