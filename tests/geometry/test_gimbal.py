"""``data.gimbal``: its forms, its one-line errors and its deterministic draws (``geometry/gimbal.py``)."""

from __future__ import annotations

import numpy as np
import pytest

from airfisheye_bench.geometry.gimbal import Gimbal
from airfisheye_bench.geometry.transforms import gimbal_rotation


def test_the_forms() -> None:
    assert Gimbal.parse(None) is None
    assert Gimbal.parse([10, 30]).fixed == (10.0, 30.0, 0.0)
    assert Gimbal.parse((10, 30, -5)).fixed == (10.0, 30.0, -5.0)
    listed = Gimbal.parse([[0, 0], [90, 45, 10]])
    assert listed.views == ((0.0, 0.0, 0.0), (90.0, 45.0, 10.0)) and listed.fixed is None
    assert Gimbal.parse({"pitch_deg": 30}).fixed == (0.0, 30.0, 0.0)  # nothing to draw
    ranged = Gimbal.parse({"yaw_deg": [-10, 10], "pitch_deg": [0, 45], "step_deg": 5, "eval": [0, 20]})
    assert ranged.ranges == ((-10.0, 10.0), (0.0, 45.0), (0.0, 0.0)) and ranged.step_deg == 5.0
    assert ranged.fixed is None and ranged.for_split(training=False).fixed == (0.0, 20.0, 0.0)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("up", "data.gimbal: expected null, [yaw, pitch]"),
        ([30], "data.gimbal: view [30]: expected [yaw, pitch] or [yaw, pitch, roll]"),
        ([[0, 0], [1, "a"]], "data.gimbal: view 1 [1, 'a']: expected"),
        ([0, float("nan")], "data.gimbal: view"),
        (
            {"pitch_deg": [45, 0]},
            "data.gimbal: pitch_deg=[45, 0]: expected a number of degrees or [low, high]",
        ),
        ({"pitch_deg": [0, 10, 20]}, "data.gimbal: pitch_deg=[0, 10, 20]"),
        ({"pitch_deg": [0, 45], "step_deg": 0}, "data.gimbal: step_deg=0: expected a number of degrees > 0"),
        ({"pitch": [0, 45]}, "data.gimbal: unknown key 'pitch'"),
        ({"pitch_deg": [0, 45], "eval": 5}, "data.gimbal: eval 5: expected"),
        ({"yaw_deg": True}, "data.gimbal: yaw_deg=True"),
    ],
)
def test_bad_values_are_one_line_naming_the_entry(value, message: str) -> None:
    with pytest.raises(ValueError) as caught:
        Gimbal.parse(value)
    assert str(caught.value).startswith(message) and "\n" not in str(caught.value)


def test_training_draws_are_deterministic_on_the_grid_and_cover_the_range() -> None:
    g = Gimbal.parse({"yaw_deg": [-20, 20], "pitch_deg": [0, 45], "step_deg": 1})
    assert g.view(5, draw=99) == g.view(5, draw=99)
    grid = set(g.all_views())
    assert g.view_count() == len(grid) == 41 * 46
    draws = [g.view(i, draw=1000 + i) for i in range(3000)]
    assert set(draws) <= grid
    pitch = np.array([v[1] for v in draws])
    assert len(set(pitch)) == 46 and abs(pitch.mean() - 22.5) < 1.0  # every grid value, uniform
    assert len({g.view(0, draw=d) for d in range(20)}) > 10  # another draw (epoch), another view


def test_evaluation_views_are_fixed_per_sample() -> None:
    g = Gimbal.parse({"pitch_deg": [0, 45]}).for_split(training=False)
    views = [g.view(i, draw=None) for i in range(200)]
    assert views == [g.view(i, draw=12345) for i in range(200)]  # no draw, no epoch: the index alone
    assert set(views) <= set(g.all_views()) and len(set(views)) > 20
    listed = Gimbal.parse([[0, 0], [0, 45], [90, 10]]).for_split(training=False)
    assert [listed.view(i, None)[1] for i in range(6)] == [0.0, 45.0, 10.0, 0.0, 45.0, 10.0]
    with pytest.raises(ValueError, match="draw"):
        Gimbal.parse([[0, 0], [0, 45]]).view(0, draw=None)  # a training split needs its draw


def test_rotation_of_a_view() -> None:
    assert Gimbal.rotation((0.0, 0.0, 0.0)) is None
    np.testing.assert_allclose(Gimbal.rotation((10.0, 30.0, 5.0)), gimbal_rotation(10.0, 30.0, 5.0))
