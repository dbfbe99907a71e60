"""The recorder: its node (node.py, a run into an MCAP bag) and the message types it finds in the
graph (graph_types.py)."""
