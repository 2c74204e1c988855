"""Shared fixtures of the TO tests: one G1 model per session (loading + symbolic build is ~1 s)."""
import os
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
for sub in ("src/lomanip_to", "src/lomanip_sim"):
    p = os.path.join(ROOT, sub)
    if p not in sys.path:
        sys.path.insert(0, p)


@pytest.fixture(scope="session")
def g1():
    from lomanip_to.model import G1Model

    return G1Model()
