"""Floor routes round object footprints (lomanip_to.route) and their use in the nominal."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.route import (ROUTE_CLEARANCE, TURN_SPAN, Footprint, point_along, shortest_route, turns,
                              walking_heading)


def _clearance(route: np.ndarray, fp: Footprint) -> float:
    pts = [point_along(route, s) for s in np.linspace(0, 1, 400)]
    return min(fp.distance(p) for p in pts)


def test_straight_line_when_free():
    fp = Footprint((5.0, 5.0), 0.0, (0.3, 0.3))
    r = shortest_route((0, 0), (1, 0), [fp])
    np.testing.assert_allclose(r, [[0, 0], [1, 0]])


def test_route_goes_round_a_block_with_clearance():
    fp = Footprint((1.0, 0.0), 0.3, (0.3, 0.4))
    r = shortest_route((0, 0), (2, 0), [fp])
    assert len(r) > 2
    assert _clearance(r, fp) >= ROUTE_CLEARANCE - 1e-3
    # no longer than going round the grown rectangle's far corners
    assert np.sum(np.linalg.norm(np.diff(r, axis=0), axis=1)) < 3.5


def test_end_next_to_an_object_shrinks_its_clearance():
    fp = Footprint((1.0, 0.0), 0.0, (0.3, 0.3))
    goal = (0.55, 0.0)                 # 0.15 m in front of it: closer than the clearance
    r = shortest_route((0.55, 1.5), goal, [fp])
    np.testing.assert_allclose(r[-1], goal)
    assert _clearance(r, fp) >= 0.9 * 0.15 - 1e-3


def test_enclosing_obstacle_is_ignored():
    fp = Footprint((0.0, 0.0), 0.0, (1.0, 1.0))
    np.testing.assert_allclose(shortest_route((0.2, 0.0), (3, 0), [fp]), [[0.2, 0], [3, 0]])


def test_point_along_is_arc_length():
    r = np.array([[0, 0], [1, 0], [1, 1]])
    np.testing.assert_allclose(point_along(r, 0.25), [0.5, 0])
    np.testing.assert_allclose(point_along(r, 0.75), [1, 0.5])
    np.testing.assert_allclose(point_along(r, 1.0), [1, 1])


@pytest.fixture(scope="module")
def s2(g1):
    # placing from 0.50 m (the fixture's side_gap until session 28): the straight walk from there to
    # the handle crosses the trolley; from 0.40 m it passes clear of it
    return load_problem("s2_trolley", {"side_gap": 0.50}, model=g1)


def test_s2_walk_to_the_handle_goes_round_the_trolley(s2, g1):
    data = ProblemData(s2, g1)
    trolley = s2.object("trolley")
    from lomanip_to.route import footprint_of

    fp = footprint_of(trolley, trolley.position, trolley.rpy())
    last = data.routes[-1]          # placing pose at the trolley's side -> behind its handle
    assert len(last) > 2
    assert _clearance(last, fp) >= 0.25
    # the warm start follows it: on the walk round (8.8-15.8 s) the base keeps clear of the trolley
    walk = (data.grid.t >= 8.8) & (data.grid.t <= 15.8)
    assert min(fp.distance(x[:2]) for x in data.x_guess[walk]) > 0.2


def test_a_long_walk_off_the_heading_turns_to_walk_forwards():
    """S1's carry: 1.25 m at 53 degrees off the heading. The heading turns to the travel direction
    over the first TURN_SPAN of the walk, holds it, and turns back to the end heading; short walks
    and walks along the heading interpolate linearly."""
    route = np.array([[0.3, 0.0], [1.05, 1.0]])
    th = np.arctan2(1.0, 0.75)
    assert turns(route, 0.0, 0.0)
    h = [walking_heading(route, s, 0.0, 0.0) for s in np.linspace(0, 1, 101)]
    assert h[0] == pytest.approx(0.0) and h[-1] == pytest.approx(0.0)
    assert walking_heading(route, TURN_SPAN, 0.0, 0.0) == pytest.approx(th)
    assert walking_heading(route, 0.5, 0.0, 0.0) == pytest.approx(th)
    assert np.max(np.abs(np.diff(h))) < 0.06  # smooth: no jump of heading along the walk
    # along the heading, short, or backwards: linear
    assert not turns(np.array([[0.0, 0.0], [1.5, 0.1]]), 0.0, 0.0)
    assert not turns(np.array([[0.0, 0.0], [0.5, 0.5]]), 0.0, 0.0)
    assert not turns(np.array([[0.0, 0.0], [-1.5, 0.0]]), 0.0, 0.0)
    assert walking_heading(np.array([[0.0, 0.0], [1.5, 0.1]]), 0.5, 0.0, 0.4) == pytest.approx(0.2)
    # a walk ending turned: it walks forwards first, then turns (wrap-around handled)
    route = np.array([[0.0, 0.0], [1.5, 0.0]])
    assert turns(route, 0.0, -1.57)
    assert walking_heading(route, 0.5, 0.0, -1.57) == pytest.approx(0.0)
    assert walking_heading(route, 1.0, 0.0, -1.57) == pytest.approx(-1.57)
    assert walking_heading(route, 0.5, 2 * np.pi, 2 * np.pi - 1.57) == pytest.approx(2 * np.pi)
