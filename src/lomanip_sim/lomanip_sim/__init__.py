"""lomanip_sim: MuJoCo world, scenarios, RGB-D camera and standing controller for the Unitree G1.

This package is the ROS-free core of the sim node: numpy/mujoco in, dataclasses out; it never
imports rclpy. Importing it selects a headless GL backend for MuJoCo (MUJOCO_GL=egl, or osmesa)
unless the user already set MUJOCO_GL, so import lomanip_sim before mujoco when rendering.

Modules: robot_model (G1 facts, model path), frames (quaternion conventions), scenario (S1/S2
parameters), world (MjSpec world builder), standing (balance controller), camera (RGB-D),
simulator (Simulation).
"""

from .camera import select_gl_backend as _select_gl_backend

_select_gl_backend()

__all__: list[str] = []
