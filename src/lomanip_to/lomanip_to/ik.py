"""Static whole-body IK that completes a hand-written keyframe into a consistent G1 configuration.

Why: a fixture keyframe is written like a demonstration (where the robot stands, its yaw, which
surface its feet are on, where its hands touch, a posture hint).  Joint angles guessed by hand do not
put the hands on the contact points, and a keyframe that contradicts the contact constraints makes
the keyframe cost fight the constraints (the S1 fixture of the last session did not converge).
This IK finds the closest configuration (to the posture hint) with:

* both soles flat at their surface height, centred at the nominal stance under the given base pose
  (+-0.119 m lateral, +0.035 m forward in the base yaw frame), or at given sole positions;
* each hand point exactly on its contact point;
* the CoM above the mid-foot point (within ``com_tol``, a static-balance proxy that ignores a held
  object's weight: named simplification);
* joint limits, base roll/pitch within +-0.3 rad.

It plays the role retargeting plays in the full pipeline (``lomanip_planner`` uses mink there); it
runs when a fixture is loaded (about 0.1-0.3 s per keyframe).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .model import FEET, HANDS, G1Model

STANCE_HALF_WIDTH = 0.119
SOLE_FORWARD = 0.035

_CACHE: dict = {}


class IKError(RuntimeError):
    """The keyframe cannot be completed (contact points out of reach)."""


def _solver(model: G1Model):
    key = id(model)
    if key in _CACHE:
        return _CACHE[key]
    x = ca.SX.sym("x", 35)
    p = ca.SX.sym("p", 53)
    th_hint = p[0:35]
    foot_xy = [p[35:37], p[37:39]]
    foot_h = [p[39], p[40]]
    hand = [p[41:44], p[44:47]]
    com_xy = p[47:49]
    w_hand = p[49:51]
    yaw_ref = p[51]
    z_ref = p[52]
    tree = model.symbolic_tree(x)
    com, _ = model.com_and_momentum(tree)
    lf = model.limb_frames(tree)
    g = []
    for i, f in enumerate(FEET):
        pt, R = lf[f]
        g += [pt[0:2] - foot_xy[i], pt[2] - foot_h[i], R[0, 2], R[1, 2],
              ca.sin(ca.atan2(R[1, 0], R[0, 0]) - yaw_ref)]
    for i, h in enumerate(HANDS):
        g.append(w_hand[i] * (lf[h][0] - hand[i]))
    g.append(com[0:2] - com_xy)
    obj = (ca.sumsqr(x[6:] - th_hint[6:]) + 10 * (x[2] - z_ref) ** 2 + 5 * ca.sumsqr(x[3:5])
           + 5 * (ca.sin(x[5] - yaw_ref)) ** 2)
    nlp = {"x": x, "p": p, "f": obj, "g": ca.vertcat(*g)}
    s = ca.nlpsol("kf_ik", "ipopt", nlp, {"print_time": False, "ipopt": {
        "print_level": 0, "sb": "yes", "max_iter": 300, "tol": 1e-8, "linear_solver": "mumps"}})
    _CACHE[key] = s
    return s


def complete_keyframe(model: G1Model, x_hint: np.ndarray, foot_heights=(0.0, 0.0), hands: dict | None = None,
                      foot_xy: dict | None = None, com_tol: float = 0.03) -> np.ndarray:
    """35-D configuration near ``x_hint`` (base pose + posture) satisfying the keyframe's contacts.

    ``hands``: {hand: world point}; ``foot_xy``: {foot: sole centre xy} (default: nominal stance
    under the hint's base pose).  Raises :class:`IKError` when the contacts cannot be met (1 mm).
    """
    x_hint = np.asarray(x_hint, float)
    hands = hands or {}
    yaw = float(x_hint[5])
    c, s = np.cos(yaw), np.sin(yaw)
    fwd, lat = np.array([c, s]), np.array([-s, c])
    nominal = {"left_foot": x_hint[:2] + SOLE_FORWARD * fwd + STANCE_HALF_WIDTH * lat,
               "right_foot": x_hint[:2] + SOLE_FORWARD * fwd - STANCE_HALF_WIDTH * lat}
    nominal.update({k: np.asarray(v, float) for k, v in (foot_xy or {}).items()})
    mid = 0.5 * (nominal["left_foot"] + nominal["right_foot"])
    p = np.concatenate([x_hint, nominal["left_foot"], nominal["right_foot"], list(foot_heights),
                        np.asarray(hands.get("left_hand", np.zeros(3)), float),
                        np.asarray(hands.get("right_hand", np.zeros(3)), float), mid,
                        [1.0 if "left_hand" in hands else 0.0, 1.0 if "right_hand" in hands else 0.0],
                        [yaw, x_hint[2]]])
    lbx = np.concatenate([np.full(3, -np.inf), [-0.3, -0.3, -np.inf], model.q_lower])
    ubx = np.concatenate([np.full(3, np.inf), [0.3, 0.3, np.inf], model.q_upper])
    n_g = 2 * 6 + 2 * 3 + 2
    lbg = np.zeros(n_g)
    ubg = np.zeros(n_g)
    lbg[-2:], ubg[-2:] = -com_tol, com_tol
    x0 = np.clip(x_hint, lbx, ubx)
    sol = _solver(model)(x0=x0, p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    x = np.array(sol["x"]).ravel()
    g = np.array(sol["g"]).ravel()
    viol = np.maximum(np.maximum(lbg - g, g - ubg), 0).max()
    if viol > 1e-3:
        raise IKError(f"keyframe contacts out of reach (residual {viol * 1e3:.1f} mm)")
    return x
