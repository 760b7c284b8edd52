"""Long-show formations: every shape keeps its spacing, the show's formations stay R apart
above the ground inside the workspace, and its legs are long enough for the limits."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from planner.families.generators import SHOW_SHAPES, formation, show_formations
from planner.methods.sequence import parse_sequence, plan_sequence


def _closest(points: np.ndarray) -> float:
    return float(cKDTree(points).query(points, 2)[0][:, 1].min())


@pytest.mark.parametrize("shape", SHOW_SHAPES)
@pytest.mark.parametrize(("count", "spacing"), [(7, 2.0), (60, 2.0), (500, 1.5)])
def test_every_shape_has_its_count_and_spacing(shape, count, spacing):
    points = formation(shape, count, spacing)
    assert points.shape == (count, 3) and np.isfinite(points).all()
    assert _closest(points) == pytest.approx(spacing, rel=1e-9)
    assert len(np.unique(points.round(6), axis=0)) == count


def test_shapes_differ_in_their_extent():
    box = {shape: np.ptp(formation(shape, 500), axis=0) for shape in SHOW_SHAPES}
    assert box["grid"][1] == 0.0 and box["carpet"][2] == 0.0  # the two planes
    assert box["torus"][2] < box["torus"][0] / 2  # a flat ring
    assert max(box["cube"]) < min(max(box[s]) for s in ("grid", "carpet", "torus"))
    with pytest.raises(ValueError, match="unknown formation shape"):
        formation("heart", 10)


@pytest.mark.parametrize("seed", [None, 0, 3])
@pytest.mark.parametrize("shapes", [SHOW_SHAPES[:5], ("carpet", "sphere", "cube", "torus",
                                                       "grid", "cylinder")])
def test_show_formations_keep_separation_ground_and_workspace(seed, shapes):
    data = show_formations(80, shapes, seed=seed)
    limits = data["limits"]
    low, high = np.array(limits["position_min"]), np.array(limits["position_max"])
    assert data["assignment"] == "free" and len(data["vehicles"]) == 80
    assert [f["name"] for f in data["formations"]] == list(shapes)
    for f in data["formations"]:
        points = np.array(f["positions"])
        assert _closest(points) >= np.sqrt(2.0) * data["min_separation"] - 1e-6
        assert points[:, 2].min() >= 2.0 - 1e-6
        assert np.all(points >= low + 2.0 - 1e-6) and np.all(points <= high - 2.0 + 1e-6)
    # every leg fits the limits: the planner accepts all of them after its own assignment
    sequence = parse_sequence(data)
    assert len(sequence.legs) == len(shapes) - 1


def test_seeds_turn_the_formations_about_the_vertical():
    plain, turned = show_formations(50, seed=None), show_formations(50, seed=1)
    for a, b in zip(plain["formations"], turned["formations"], strict=True):
        pa, pb = np.array(a["positions"]), np.array(b["positions"])
        np.testing.assert_allclose(pa[:, 2], pb[:, 2], atol=1e-5)  # same heights
        np.testing.assert_allclose(np.hypot(pa[:, 0], pa[:, 1]), np.hypot(pb[:, 0], pb[:, 1]),
                                   atol=1e-5)  # same distances from the vertical axis
    assert not np.allclose(plain["formations"][0]["positions"],
                           turned["formations"][0]["positions"])


def test_a_small_five_formation_show_plans_and_verifies():
    show = plan_sequence(show_formations(24, seed=2, hold=1.0))
    assert show.status == "converged", show.message
    assert len(show.legs) == 4 and all(leg.ok for leg in show.legs)
    assert show.verification.verified and show.dynamics_error < 1e-9
    assert show.verification.min_separation_continuous >= 1.0 - 1e-4


def test_show_formations_refuse_what_cannot_be_a_show():
    with pytest.raises(ValueError, match="two formations"):
        show_formations(10, ["grid"])
    with pytest.raises(ValueError, match="under the separation"):
        show_formations(10, spacing=0.5)
