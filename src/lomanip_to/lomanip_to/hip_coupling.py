"""Coupled hip limit: in deep hip flexion the hip-roll link meets the pelvis unless the thigh is abducted.

The G1's joint ranges are independent boxes, but its meshes are not: with the hip pitched past about
-1.3 rad an adducted thigh drives the hip-roll link into the pelvis. S1's pick-up squat planned the left
hip at pitch -2.0, roll -0.45; under physics that link pressed 70 N into the pelvis, the hip roll
stayed 0.4 rad off its plan and the robot fell in the lift (docs/execution.md, session 18).

Collision spheres cannot model this pair (the links touch at a joint), so it is a joint-space bound
that depends only on the hip pitch (the hip-roll and hip-yaw links are children of the roll joint):

    outward_roll >= bound(pitch) = M - K softplus(S (pitch - H0)) / S

``outward_roll`` is the roll away from the body's midline (left: +roll, right: -roll). The
constants were fitted to the zero-distance boundary of MuJoCo's meshes (pelvis against the hip-roll
and hip-yaw links, swept over pitch in [-2.53, -0.8]) and shifted 0.04 rad inside it:
``tests/to/test_hip_coupling.py`` sweeps the meshes again and checks both sides.

The retargeting's keyframes are not held to it (S1's pick keyframe lies 0.04 rad past it, at the
meshes' boundary): with the bound as an IK limit the squatting start could not recover, and S1's
squat became a stoop (pelvis 0.58 m instead of 0.22 m) whose carry nominal broke.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

HIP_COUPLING_M = 0.0313
HIP_COUPLING_K = 1.3001
HIP_COUPLING_S = 5.0139
HIP_COUPLING_H0 = -1.4086

#: index in the 29 joints (G1_JOINT_NAMES order) of each side's hip pitch and hip roll, and the
#: sign that turns the roll into an outward (abducting) angle
HIP_JOINTS = {"left": (0, 1, 1.0), "right": (6, 7, -1.0)}


def hip_roll_bound(pitch):
    """The least outward roll that keeps the hip-roll link off the pelvis at this hip pitch."""
    if isinstance(pitch, (ca.SX, ca.MX, ca.DM)):
        sp = ca.log1p(ca.exp(HIP_COUPLING_S * (pitch - HIP_COUPLING_H0)))
    else:
        sp = np.logaddexp(0.0, HIP_COUPLING_S * (np.asarray(pitch, float) - HIP_COUPLING_H0))
    return HIP_COUPLING_M - HIP_COUPLING_K * sp / HIP_COUPLING_S


def hip_roll_clearance(q):
    """(left, right) outward roll minus its bound, for the 29 joint angles ``q``: >= 0 is feasible."""
    out = [sign * q[roll] - hip_roll_bound(q[pitch]) for pitch, roll, sign in HIP_JOINTS.values()]
    if isinstance(q, (ca.SX, ca.MX, ca.DM)):
        return ca.vertcat(*out)
    return np.array(out, float)
