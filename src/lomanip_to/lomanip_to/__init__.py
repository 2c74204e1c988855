"""Whole-body trajectory optimisation for the G1: centroidal dynamics with full kinematics."""
