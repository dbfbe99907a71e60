"""The viewer: its node (node.py) and the live view it feeds (live_view.py, Foxglove)."""
