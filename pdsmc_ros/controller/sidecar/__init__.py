"""A real-time controller's sidecar processes: the Python work that would hold the interpreter's
lock beside the control loop, run in children of its own (the real-time design: docs/explanation/realtime.md).

framing.py: the one framing they speak (length-prefixed pickles over pipes, non-blocking in the
loop's process); process.py: a child's life (started with pipes, seen stopped in /proc, killed,
replaced by a spare started ahead); gain_check.py: a gain change's stability check, in a child
(:class:`~.gain_check.CheckProcess`) or in the caller (:func:`~.gain_check.checked`).
"""
