"""Scoring's values do not move when it is made faster (issue 52): the rows of 50 scored
views (:mod:`tests.bench.scoring_cases`: items of ``pose-3dof`` and ``known-pose``, each with
the truth, a damaged estimate, another instance's shape, an empty and a full one) equal,
bit for bit, those the scoring code wrote before its speed-up
(``tests/bench/data/scoring_reference.json``); and scoring a grid kept by content (the
oracle's, a class mean) gives what computing it again gives."""

from __future__ import annotations

import json

import numpy as np
import pytest

from beo_bench.bench import scoring as S
from tests.bench import scoring_cases


@pytest.fixture(scope="module")
def rows() -> dict:
    return scoring_cases.rows()


def test_every_scored_value_is_the_unchanged_codes(rows) -> None:
    want = json.loads(scoring_cases.REFERENCE.read_text())
    assert sorted(rows) == sorted(want)
    # exact: json keeps a float's shortest repr, which reads back as the same double
    got = json.loads(json.dumps(rows))
    diff = {
        f"{case}:{k}": (got[case].get(k), v)
        for case, row in want.items()
        for k, v in row.items()
        if got[case].get(k) != v
    }
    assert not diff, diff


def test_a_grid_kept_by_content_scores_as_one_computed_again() -> None:
    """The content caches hand out what a fresh computation gives, and never another
    grid's: a grid differing in one cell gets its own surface and EDT."""
    from beo_bench.objects import ObjectSet

    v = S.truth_shape(ObjectSet("test", ["mug"]).get("mug", 0).key, 32).voxels
    g = v.astype(np.float32)
    kept = S.grid_surface(g)
    assert kept is S.grid_surface(v)  # the truth's own, by content
    S._SURFACES.clear()
    S._EDTS.clear()
    fresh = S.grid_surface(g)
    assert fresh is not kept
    np.testing.assert_array_equal(fresh.triangles, kept.triangles)
    np.testing.assert_array_equal(fresh.samples, kept.samples)
    h = g.copy()
    h[16, 16, 16] = 1.0 - h[16, 16, 16]
    assert S.grid_surface(h) is not fresh
    occupied = v.copy()
    assert S.grid_edt(occupied) is S.grid_edt(v.copy())
    occupied[0, 0, 0] = not occupied[0, 0, 0]
    assert not np.array_equal(S.grid_edt(occupied), S.grid_edt(v))
    with pytest.raises(ValueError):  # read-only: a caller cannot spoil the next view's
        kept.samples[0, 0] = 1.0
