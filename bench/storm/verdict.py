"""The storm benchmark's verdict: each storm/idle ratio with its 95 % interval (a paired bootstrap over
the rounds; an exact Poisson rate ratio for missed deadlines) against the 1.2x target."""

from __future__ import annotations

import numpy as np

from pdsmc_ros.loop.statistics import missed


def ratio(storm: float, idle: float) -> float:
    return storm / idle if idle > 0 else float("inf") if storm > 0 else 1.0


TARGET = 1.2  # issue 37: the storm's lateness within this factor of idle


LEVEL = 0.95  # the intervals' coverage


RESAMPLES = 2000  # bootstrap resamples of the rounds


SEED = 37


VERDICT_ROUNDS = 8  # fewer rounds: a bootstrap over so few draws understates the spread between them


def round_lateness(rows: np.ndarray, windows: list[tuple[str, float, float, str]]) -> dict[str, list[np.ndarray]]:
    """Each window's lateness (s), by kind, in round order (round ``k`` is the ``k``-th of each kind)."""
    found: dict[str, list[np.ndarray]] = {"idle": [], "storm": []}
    for kind, a, b, _ in windows:
        found[kind].append(rows[(rows[:, 0] >= a) & (rows[:, 0] < b), 3])
    return found


def ratio_intervals(idle: list[np.ndarray], storm: list[np.ndarray], period: float, *,
                    resamples: int = RESAMPLES, level: float = LEVEL, seed: int = SEED
                    ) -> dict[str, tuple[float, float, float]]:
    """Each metric's storm/idle ratio, pooled over the rounds, with its ``level`` interval.

    p99, p99.9 and worst: a percentile bootstrap over the rounds (Efron and Tibshirani 1993,
    Section 13.3), paired: a resample draws ``R`` rounds with replacement and pools both kinds of
    window of the rounds drawn, so that what drifts between rounds (the machine's load, the host)
    moves both sides of a ratio. Missed deadlines: rare events, a Poisson count in each kind of
    window; given their total, the storm's share is binomial, and the Clopper-Pearson interval of
    that share gives the exact interval of the rate ratio (Clopper and Pearson 1934).
    """
    rounds = len(idle)
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, rounds, (resamples, rounds))
    metrics = {"p99": 99.0, "p99.9": 99.9, "worst": 100.0}
    found: dict[str, tuple[float, float, float]] = {}
    both = {"idle": idle, "storm": storm}
    pooled = {kind: np.concatenate(parts) for kind, parts in both.items()}
    boot = {name: np.empty(resamples) for name in metrics}
    for i, drawn in enumerate(draws):
        taken = {kind: np.concatenate([parts[k] for k in drawn]) for kind, parts in both.items()}
        values = {kind: np.percentile(taken[kind], list(metrics.values())) for kind in both}
        for j, name in enumerate(metrics):
            boot[name][i] = ratio(values["storm"][j], values["idle"][j])
    tail = 100.0 * (1.0 - level) / 2.0
    for name, q in metrics.items():
        point = ratio(float(np.percentile(pooled["storm"], q)), float(np.percentile(pooled["idle"], q)))
        low, high = np.percentile(boot[name], [tail, 100.0 - tail])
        found[name] = (point, float(low), float(high))
    found["missed"] = rate_ratio_interval(int(np.count_nonzero(missed(pooled["storm"], period))), len(pooled["storm"]),
                                          int(np.count_nonzero(missed(pooled["idle"], period))), len(pooled["idle"]),
                                          level=level)
    return found


def rate_ratio_interval(storm: int, storm_ticks: int, idle: int, idle_ticks: int, *, level: float = LEVEL
                        ) -> tuple[float, float, float]:
    """The ratio of two Poisson rates, ``(storm / storm_ticks) / (idle / idle_ticks)``, and its exact
    ``level`` interval: given ``storm + idle`` events, the storm's share is binomial, and the
    Clopper-Pearson interval of that share maps onto the ratio (Clopper and Pearson 1934)."""
    from scipy.stats import beta

    total = storm + idle
    if total == 0:
        return 1.0, 0.0, float("inf")
    alpha = 1.0 - level
    share_low = float(beta.ppf(alpha / 2, storm, idle + 1)) if storm > 0 else 0.0
    share_high = float(beta.ppf(1 - alpha / 2, storm + 1, idle)) if idle > 0 else 1.0

    def rate_ratio(share: float) -> float:  # the storm's share of the events -> the ratio of the rates
        return share / (1.0 - share) * idle_ticks / storm_ticks if share < 1.0 else float("inf")

    return rate_ratio(storm / total), rate_ratio(share_low), rate_ratio(share_high)


def verdict(low: float, high: float, target: float = TARGET) -> str:
    """Whether an interval shows the ratio within ``target``, beyond it, or neither."""
    if high <= target:
        return f"within {target:g}x"
    if low > target:
        return f"beyond {target:g}x"
    return "undecided (the interval holds the target)"
