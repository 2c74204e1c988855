"""Collision rows screened by distance: only the (pair, knot) rows near contact go to ipopt.

Why: one window serves every knot, so every collision pair has its hard row, its homotopy surrogate
row and its slack at every knot. On the demo push that is 4824 + 4824 object rows, 3150
self-collision rows and 1800 floor rows of the final stage's 21567; nearly all of them are
centimetres to metres from their bound, where they and their penalties are flat (zero value, zero
derivatives), yet each inequality row adds a slack and two dimensions to ipopt's KKT system, and
each surrogate row a slack variable. Leaving out the rows that are far from their bound at the
stage's start point (``Options.collision_screen_distance``) is TrajOpt's practice (only pairs
within a check distance enter the QP). A screened row is not dropped silently: after the stage,
every screened row is evaluated at the result, and a row that does not hold there brings the stage
back with the rows screened again at the new point (see ``solver._run_stages``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .transcription import Window

#: a pair's homotopy surrogate row is screened only where the surrogate's value F is at least
#: this (F = 1 on the surrogate's surface; its penalty max(1 - F, 0)^2 is flat beyond it)
SURROGATE_FAR = 2.0


@dataclass(frozen=True)
class RowKinds:
    """Window-row indices of the screenable rows (per window, built once per structure)."""

    distance: np.ndarray        # rows whose value is a distance in m: object pairs, carried objects, floor
    surrogate: np.ndarray       # homotopy surrogate rows (F - 1 + s), one per object pair
    surrogate_pair_row: np.ndarray  # the same pair's distance row, per surrogate row
    slack: np.ndarray           # window-variable index of each surrogate row's slack
    self_rows: np.ndarray       # self-collision rows (|ci - cj|^2 - R^2, m^2)
    self_reach: np.ndarray      # R of each self row without the margin parameter (sum of radii)


def row_kinds(win: Window) -> RowKinds:
    """Classify the window's collision rows by name (``transcription.Window`` adds them)."""
    G = win.G.blocks
    npairs = len(win.st.obj_pairs)
    distance = [G[f"c{i} collision"].start for i in range(npairs)]
    distance += [s.start for k, s in G.items() if re.fullmatch(r"e\d+ carried object collision", k)]
    distance += list(range(G["floor clearance"].start, G["floor clearance"].stop))
    surrogate = [G[f"c{i} homotopy surrogate"].start for i in range(npairs)]
    pair_row = [G[f"c{i} collision"].start for i in range(npairs)]
    slack = [win.W["slack"].start + i for i in range(npairs)] if npairs else []
    spheres = win.model.spheres
    self_rows, reach = [], []
    for (a, b) in win.st.self_pairs:
        self_rows.append(G[f"self {a} {b}"].start)
        reach.append(spheres[a].radius + spheres[b].radius)
    as_int = lambda v: np.asarray(v, dtype=np.int64)  # noqa: E731
    return RowKinds(as_int(distance), as_int(surrogate), as_int(pair_row), as_int(slack), as_int(self_rows),
                    np.asarray(reach, float))


@dataclass
class Screen:
    """What a stage left out: global row indices (into g) and slack indices (into z)."""

    rows: np.ndarray
    slacks: np.ndarray

    @property
    def empty(self) -> bool:
        return self.rows.size == 0


def _global(rows: np.ndarray, K: int, n: int) -> np.ndarray:
    """Window-row (or window-variable) indices -> global indices at every knot, knot-major."""
    return (np.arange(K)[:, None] * n + rows[None, :]).ravel()


def far_rows(kinds: RowKinds, win: Window, K: int, g: np.ndarray, z: np.ndarray, lbg: np.ndarray,
             self_margin: np.ndarray, distance: float, fraction: float = 1.0) -> Screen:
    """The screenable rows whose value at ``g`` (all rows, evaluated at ``z``) lies farther than
    ``fraction * distance`` from their lower bound; each surrogate row goes with its pair's distance
    row and its slack. ``lbg``: the stage's lower bounds (a switched-off row is never returned:
    screening applies to bounded rows only). ``self_margin``: the margin parameter per knot."""
    ng, nw = win.G.n, win.W.n
    far = fraction * distance
    G = np.asarray(g, float).reshape(K, ng)
    L = np.asarray(lbg, float).reshape(K, ng)
    out_rows, out_slacks = [], []
    if kinds.distance.size:
        lb = L[:, kinds.distance]
        gap = G[:, kinds.distance] - np.where(np.isfinite(lb), lb, 0.0)
        kk, jj = np.nonzero(np.isfinite(lb) & (gap > far))
        out_rows.append(kk * ng + kinds.distance[jj])
    if kinds.surrogate.size:
        Z = np.asarray(z, float).reshape(K + 1, nw)[:K]
        s = Z[:, kinds.slack]
        F = G[:, kinds.surrogate] + 1.0 - s          # the surrogate's value without its slack
        pair_gap = G[:, kinds.surrogate_pair_row]    # exact distance of the same pair (m)
        on = np.isfinite(L[:, kinds.surrogate])
        sur_far = 1.0 + fraction * (SURROGATE_FAR - 1.0)
        kk, jj = np.nonzero(on & (F >= sur_far) & (pair_gap > far))
        out_rows.append(kk * ng + kinds.surrogate[jj])
        out_slacks.append(kk * nw + kinds.slack[jj])
    if kinds.self_rows.size:
        lb = L[:, kinds.self_rows]
        R = kinds.self_reach[None, :] + np.asarray(self_margin, float).reshape(K, 1)
        gap = np.sqrt(np.maximum(G[:, kinds.self_rows] + R ** 2, 0.0)) - R   # surface-to-surface (m)
        kk, jj = np.nonzero(np.isfinite(lb) & (gap > far))
        out_rows.append(kk * ng + kinds.self_rows[jj])
    rows = np.sort(np.concatenate(out_rows)) if out_rows else np.zeros(0, np.int64)
    slacks = np.sort(np.concatenate(out_slacks)) if out_slacks else np.zeros(0, np.int64)
    return Screen(rows.astype(np.int64), slacks.astype(np.int64))


def violated_rows(screen: Screen, kinds: RowKinds, win: Window, K: int, g: np.ndarray, z: np.ndarray,
                  lbg: np.ndarray, self_margin: np.ndarray, distance: float, fraction: float = 0.0) -> int:
    """How many of a stage's screened rows are at or past their bound at ``z`` (``fraction`` > 0:
    nearer it than that fraction of the screening distance). Why only those: a screened row that
    holds strictly at a stage's result would have had a zero multiplier there, so the result is a
    KKT point of the stage with every row; one that does not hold means the stage must be solved
    again with it."""
    still_far = far_rows(kinds, win, K, g, z, lbg, self_margin, distance, fraction)
    return int(np.setdiff1d(screen.rows, still_far.rows, assume_unique=True).size)
