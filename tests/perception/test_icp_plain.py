"""``icp-plain``: the dissertation's ICP baseline is ``icp`` from one start
(upright and facing the camera, or yaw 0 about a given up), with every pair kept,
point-to-point steps and no free-space term. It must be a correct ICP (exact from a near
start) that, unlike the multi-start ``icp``, gets stuck in local minima from a far one."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from beo_bench.backend import (
    ClassHint,
    backend_options,
    check_backend,
    get_backend,
    get_spec,
    sample_views,
)
from beo_bench.errors import UsageError
from beo_bench.perception.icp.backend import PLAIN_DEFAULTS, UPRIGHT, ICPBackend
from tests.perception.test_icp import FAST, _angle_deg, _synthetic_view

OFFSET = np.array([0.02, -0.01, 0.0])


@pytest.fixture(scope="module")
def plain() -> ICPBackend:
    return get_backend("icp-plain", **FAST)


def test_icp_plain_is_icp_with_the_plain_defaults(plain) -> None:
    opts = backend_options("icp-plain")
    assert opts is not None
    for key, value in PLAIN_DEFAULTS.items():
        assert opts[key] == value and getattr(plain.options, key) == value
    # every other option is icp's, with icp's default
    icp_opts = backend_options("icp")
    assert icp_opts is not None and set(opts) == set(icp_opts)
    assert {k: v for k, v in opts.items() if k not in PLAIN_DEFAULTS} == {
        k: v for k, v in icp_opts.items() if k not in PLAIN_DEFAULTS
    }
    caps = get_spec("icp-plain").capabilities_of(plain.options)
    assert plain.name == "icp-plain" and caps.class_hint is ClassHint.OPTIONAL
    # its options are checked like any backend's
    with pytest.raises(UsageError, match=r"no option 'startz'.*starts \(an integer, default 1\)"):
        get_backend("icp-plain", startz=2)
    assert get_backend("icp-plain", trim=0.8, **FAST).options.trim == 0.8


def test_icp_plain_conforms(plain) -> None:
    views = sample_views(2)
    check_backend(plain, views)
    e = plain.predict(views[0])
    assert e.info["starts"] == 1 and e.class_index == views[0].class_hint


def test_the_one_3dof_start_is_upright_and_facing_the_camera() -> None:
    assert np.allclose(UPRIGHT @ UPRIGHT.T, np.eye(3)) and np.isclose(np.linalg.det(UPRIGHT), 1)
    np.testing.assert_array_equal(UPRIGHT[:, 2], [0, -1, 0])  # up: image up (OpenCV y down)
    np.testing.assert_array_equal(UPRIGHT[:, 0], [0, 0, -1])  # front: towards the camera
    b = ICPBackend(starts=1, **FAST)
    np.testing.assert_array_equal(b._start_rotations(None, None), UPRIGHT[None])  # no prior


def test_from_a_near_start_it_is_exact_and_its_score_is_the_plain_residual(plain) -> None:
    view, R, t = _synthetic_view("sofa", 90.0, OFFSET)
    e = plain.predict(replace(view, up_hint=R[:, 2]))
    assert _angle_deg(e.rotation, R) < 2.0
    assert np.linalg.norm(e.translation - t) < 0.01
    assert e.info["score_mm"] == e.info["residual_mm"]  # no free-space term


@pytest.mark.parametrize("yaw", [10.0, 20.0, 200.0])
def test_from_a_far_start_it_gets_stuck_where_multi_start_icp_does_not(plain, yaw) -> None:
    """The dissertation's plain ICP "got stuck in local minima": the same synthetic views
    that ``icp`` recovers to within two degrees leave ``icp-plain`` in a local minimum: from
    10 deg and 200 deg off it ends tens of degrees away, from 20 deg about 11 deg away (the
    sofa of library version 2). Either is a miss at the 5 deg of the 5deg/5cm accuracy."""
    view, R, _ = _synthetic_view("sofa", yaw, OFFSET)
    view = replace(view, up_hint=R[:, 2])
    strong = get_backend("icp", **FAST).predict(view)
    assert _angle_deg(strong.rotation, R) < 2.0
    assert _angle_deg(plain.predict(view).rotation, R) > 5.0


def test_without_the_class_it_picks_the_lowest_residual(plain) -> None:
    view, R, _ = _synthetic_view("sofa", 90.0, OFFSET)
    e = plain.predict(replace(view, up_hint=R[:, 2], class_hint=None))
    scores = e.info["class_scores_mm"]
    assert len(scores) == len(view.categories)
    assert e.class_index == int(np.argmin(scores)) == view.class_hint
