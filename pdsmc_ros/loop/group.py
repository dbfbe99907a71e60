"""Several node wrappers of one process seen as one by the serve loop (:mod:`.process`)."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

from .realtime import AUTO_BUSY_WAIT
from .realtime_params import LoopReport


class NodeGroup:
    """Several node wrappers seen as one: done when all are, failed if any is."""

    def __init__(self, wrappers: Sequence[Any], reports: Sequence[LoopReport] = ()) -> None:
        self.wrappers = list(wrappers)
        stats = {id(r.diagnostics.node): r.stats for r in reports if r.diagnostics is not None}
        # the ticking nodes, each with its loop statistics (None: not a loop node)
        self.ticking = [(w, stats.get(id(w.node))) for w in self.wrappers if getattr(w, "period", None)]
        # real time: work a node does off its tick, in the loop's spare time (``idle(until)``)
        self.idlers = [w.idle for w in self.wrappers if callable(getattr(w, "idle", None))]
        self.stopped_by_signal: str | None = None
        periods = {getattr(w, "period", None) for w in self.wrappers} - {None}
        self.period = min(periods) if periods else None
        # the largest spin a ticking node was given, else automatic (every one left at -1)
        self.busy_wait = max((getattr(w, "busy_wait", AUTO_BUSY_WAIT) for w in self.wrappers
                              if getattr(w, "period", None)), default=AUTO_BUSY_WAIT)
        # real time, composed: the plant's node stays in the graph after its run, so the
        # nodes that watch for it to leave are told when it is done
        self.state_sources = [w for w in self.wrappers if getattr(w, "publishes_states", False)]
        self.watchers = [w.plant_watch for w in self.wrappers if getattr(w, "plant_watch", None)]

    @property
    def done(self) -> bool:
        for w in self.wrappers:  # noqa: SIM110 (checked at every pass of the loop: no generator)
            if not w.done:
                return False
        return True

    @done.setter
    def done(self, value: bool) -> None:  # set by the signal handler
        for w in self.wrappers:
            w.done = value

    @property
    def exit_code(self) -> int:
        return max(w.exit_code for w in self.wrappers)

    def tick(self, lateness: float) -> None:
        clock = time.perf_counter
        deadline = clock() - lateness
        for w, stats in self.ticking:
            if not w.done:
                start = clock()
                w.tick(lateness)
                if stats is not None:  # ros2_control's overrun accounting, per node
                    stats.record(start, start - deadline, clock())
        if self.watchers and self.state_sources and all(w.done for w in self.state_sources):
            for watch in self.watchers:
                if not watch.gone:
                    watch.gone = True
                    watch.on_gone()
