"""Orchestrator of the lomanip graph: starts the nodes, records rosbag2 bags, summarises them."""
