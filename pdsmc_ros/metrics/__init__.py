"""A run's figures: the thesis's statistics (statistics.py), the scores beside them (scores.py), and
the compiled accumulators that gather both instant by instant (kernel.py). ROS-free."""
