"""A real-time controller's sidecar processes: the Python work that would hold the interpreter's
lock beside the control loop, run in children of its own (docs/explanation/realtime.md).

framing.py: the one framing they speak (length-prefixed pickles over pipes, non-blocking in the
loop's process); process.py: a child's life (started with pipes, seen stopped in /proc, killed,
replaced by a spare started ahead). The goal process: goal_process.py (the loop's side:
:class:`~.goal_process.GoalProcess`), goal_child.py (the child's program), remote_view.py (the
controller as the child's action server sees it), parameter_stand_in.py (the controller's
parameter services in the child), lost_results.py (the action's get_result service in the
controller's process: the result of a goal lost with the child). The gain check: gain_check.py
(a gain change's stability check, in a child, :class:`~.gain_check.CheckProcess`, or in the
caller, :func:`~.gain_check.checked`).
"""
