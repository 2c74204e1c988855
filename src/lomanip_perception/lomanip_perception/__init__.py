"""Perception: prompts and RGB-D to 3D contacts per subtask."""
