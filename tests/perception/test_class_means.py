"""The baselines' class means are published (``perception/published/class-means``), so
that no run builds the 3,600 training instances for them: stored losslessly, read back
bitwise as computed, and used only where they are the means asked for."""

from __future__ import annotations

import numpy as np
import pytest

from beo_bench.objects import LIBRARY_VERSION, categories
from beo_bench.perception import means, published


def test_the_stored_counts_read_back_as_the_mean_bitwise() -> None:
    rng = np.random.default_rng(0)
    grids = rng.random((2, 7, 4, 4, 4)) < rng.random((2, 1, 4, 4, 4))  # 2 classes, 7 each
    grids[1, 2:] = False  # a class of 2 instances: another n
    n = np.asarray([7, 2])
    counts = np.stack([grids[0].sum(0), grids[1, :2].sum(0)]).astype(np.uint8)
    got = means.means_arrays(counts, n, np.zeros((2, 3)))
    want = np.asarray([grids[0].mean(0), grids[1, :2].mean(0)], dtype=np.float32)
    assert got.shape.dtype == np.float32 and got.shape.tobytes() == want.tobytes()


def test_the_library_means_are_read_not_computed(monkeypatch) -> None:
    def refuse(*a, **k):
        raise AssertionError("the published means were computed again")

    monkeypatch.setattr(means, "training_voxels", refuse)
    meta, _ = published.read(means.CLASS_MEANS_STEM)
    assert meta["library_version"] == LIBRARY_VERSION and meta["D"] == 32
    assert meta["categories"] == list(categories()) and meta["version"] == means.MEANS_VERSION
    cats = ("sofa", "box")  # any subset, in any order
    m = means.class_means(cats)
    full = means.class_means(tuple(categories()))
    idx = [list(categories()).index(c) for c in cats]
    assert m.categories == cats and np.array_equal(m.shape, full.shape[idx])
    assert m.shape.shape == (2, 32, 32, 32) and m.size.shape == (2, 3)
    # other settings are not the published means: computed (here: refused)
    with pytest.raises(AssertionError, match="computed again"):
        means.class_means(cats, per_category=3)
    with pytest.raises(AssertionError, match="computed again"):
        means.class_means(cats, resolution=16)


@pytest.mark.slow
def test_the_published_means_are_the_computed_ones(monkeypatch) -> None:
    """One class's means computed from its 200 training instances equal the published
    ones bitwise (the cheapest class to build: box)."""
    pub = means.published_class_means(("box",), 32)
    assert pub is not None
    monkeypatch.setattr(means, "published_class_means", lambda c, r: None)
    ref = means.class_means(("box",))
    assert pub.shape.tobytes() == ref.shape.tobytes() and pub.size.tobytes() == ref.size.tobytes()
