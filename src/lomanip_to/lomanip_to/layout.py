"""Named slices of flat vectors (knot variables, knot parameters, window constraint rows)."""

from __future__ import annotations

import casadi as ca
import numpy as np


class Layout:
    """Ordered named blocks of a flat vector, with CasADi SX symbols on demand."""

    def __init__(self, name: str):
        self.name = name
        self.blocks: dict[str, slice] = {}
        self.n = 0

    def add(self, key: str, size: int) -> slice:
        if key in self.blocks:
            raise KeyError(f"{self.name}: duplicate block {key}")
        s = slice(self.n, self.n + int(size))
        self.blocks[key] = s
        self.n += int(size)
        return s

    def __getitem__(self, key: str) -> slice:
        return self.blocks[key]

    def __contains__(self, key: str) -> bool:
        return key in self.blocks

    def split(self, vec):
        return {k: vec[s] for k, s in self.blocks.items()}

    def zeros(self, n_cols: int | None = None) -> np.ndarray:
        return np.zeros(self.n) if n_cols is None else np.zeros((self.n, n_cols))

    def row_names(self) -> list[str]:
        out = [""] * self.n
        for k, s in self.blocks.items():
            for i in range(s.start, s.stop):
                out[i] = k
        return out


def sx_split(lay: Layout, sym: ca.SX) -> dict:
    return {k: sym[s] for k, s in lay.blocks.items()}
