"""The rows' linearisation point on a chord past an upright cylinder: the closed form agrees
with the golden-section search it replaces there, and boxes still take the search."""

from __future__ import annotations

import numpy as np

from planner.model.obstacle_set import ObstacleSet
from planner.model.obstacles import parse_obstacles
from planner.scp.obstacle_rows import chord_nearest, row_point

TREES, _ = parse_obstacles({"obstacles": [
    {"id": "tree", "cylinder": {"center": [5.0, 5.0], "radius": 0.4, "z": [0.0, 4.0]}},
    {"id": "crate", "box": {"min": [1.0, 1.0, 0.0], "max": [2.0, 2.0, 1.0]}},
]}, 0.8)


def test_the_closed_form_point_is_the_nearest_on_chords_past_an_upright_cylinder() -> None:
    geometry = ObstacleSet.build(TREES)
    rng = np.random.default_rng(3)
    a = np.column_stack([rng.uniform(2, 8, 400), rng.uniform(2, 8, 400), rng.uniform(0, 4, 400)])
    b = np.column_stack([rng.uniform(2, 8, 400), rng.uniform(2, 8, 400), rng.uniform(0, 4, 400)])
    o = np.zeros(400, dtype=np.intp)
    fast, slow = row_point(geometry, a, b, o), chord_nearest(geometry, a, b, o)
    d_fast = geometry.signed_distance(fast, o)
    d_slow = geometry.signed_distance(slow, o)
    outside = d_slow > 0
    assert outside.sum() > 100
    # never farther than the search's point, and the same point up to its tolerance
    assert np.all(d_fast[outside] <= d_slow[outside] + 1e-9)
    assert np.allclose(fast[outside], slow[outside], atol=1e-3)
    assert np.all(d_fast[~outside] < 0.0)  # a chord through the trunk still says so
    # a chord leaving the cylinder's height, and a box, keep the search
    cases = ((np.array([[4.0, 3.0, 3.0]]), np.array([[6.0, 3.0, 5.0]]), 0),
             (np.array([[0.0, 0.0, 0.5]]), np.array([[3.0, 0.5, 0.5]]), 1))
    for one, other, obstacle in cases:
        index = np.array([obstacle])
        assert np.allclose(row_point(geometry, one, other, index),
                           chord_nearest(geometry, one, other, index))
