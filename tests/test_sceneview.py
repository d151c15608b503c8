"""``beo-bench view`` writes a PNG a person can look at and a rerun recording."""

from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np

from beo_bench.cli import main
from beo_bench.sceneview import colour_segmentation


def test_view_writes_png_and_rrd(tmp_path, capsys) -> None:
    assert main(["view", "--seed", "1", "--out", str(tmp_path), "--image-size", "96", "72"]) == 0
    png, rrd = tmp_path / "scene_1.png", tmp_path / "scene_1.rrd"
    img = mpimg.imread(png)
    assert img.ndim == 3 and img.shape[1] > img.shape[0] and img.std() > 0.05
    data = rrd.read_bytes()
    assert data[:4] == b"RRF2" and len(data) > 10_000  # meshes, images and points inside
    assert not list(tmp_path.glob(".*.tmp"))  # written atomically
    assert "target" in capsys.readouterr().out


def test_segmentation_colours_keep_background_black() -> None:
    seg = np.array([[0, 1], [2, 9]])
    c = colour_segmentation(seg)
    assert c.shape == (2, 2, 3) and c.dtype == np.uint8
    assert (c[0, 0] == 0).all() and (c[0, 1] > 0).any() and not (c[0, 1] == c[1, 0]).all()
    np.testing.assert_array_equal(c[1, 1], c[0, 1])  # labels wrap around the 8 colours


def test_depth_colour_range_is_the_objects_not_the_floors() -> None:
    """The depth panel's colours span the objects' depths (and a margin for the table
    around them), not the floor's far-away pixels, which would flatten the objects."""
    from beo_bench.sceneview import DEPTH_MARGIN_M, depth_range

    depth = np.full((60, 80), 2.7)  # the floor
    depth[:, :10] = 0.0  # no hit
    seg = np.zeros((60, 80), dtype=np.int32)
    depth[20:40, 20:40], seg[20:40, 20:40] = np.linspace(1.0, 1.2, 20)[None, :], 1
    lo, hi = depth_range(depth, seg)
    assert 1.0 - DEPTH_MARGIN_M - 0.01 <= lo < 1.0 and 1.2 < hi <= 1.2 + DEPTH_MARGIN_M + 0.01
    # without object pixels: every hit's depths (the floor here), never the no-hit zeros
    assert depth_range(depth, np.zeros_like(seg))[0] > 0.5
