"""Retargeting, keyframes, contact schedule and the plan service."""
