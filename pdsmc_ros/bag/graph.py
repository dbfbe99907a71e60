"""Bags of a graph the recorder did not start (its graph mode): what they hold, read back.

ROS-free (rosbags): the analysis of a real arm's run (:mod:`pdsmc_ros.experiments.runs`) reads them.
"""

from __future__ import annotations

RECORDING_KEY = "pdsmc_ros.recording"
"""``metadata.yaml`` custom data of a graph recording: JSON of its topics, types and counts."""
