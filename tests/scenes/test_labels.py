"""Segmentation labels are exactly what MuJoCo's own segmentation pass says: on BEOPick
scenes, isolated views and models with many geoms or many labels (uint8 below 255 labels,
int32 above); depth is unaffected by drawing labels."""

from __future__ import annotations

import numpy as np
import pytest

from beo_bench.objects import ObjectSet
from beo_bench.scenes import IsolatedRenderer, look_at
from beo_bench.scenes.builder import build_isolated
from beo_bench.scenes.camera import OBJECT_RIG, Intrinsics
from beo_bench.scenes.gl import load_mujoco
from beo_bench.scenes.renderer import CAMERA_NAME, Renderer

mujoco = load_mujoco()
GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)


def mujoco_labels(model, data, geom_labels: np.ndarray) -> np.ndarray:
    """The labels of the view the depth camera last rendered, from ``mujoco.Renderer``'s
    segmentation (object id and type per pixel): the reference, independent of ours."""
    h, w = model.vis.global_.offheight, model.vis.global_.offwidth
    with mujoco.Renderer(model, h, w) as raw:
        raw.enable_segmentation_rendering()
        raw.update_scene(data, camera=CAMERA_NAME)
        ids = raw.render()
    objid, objtype = ids[..., 0], ids[..., 1]
    out = np.zeros(objid.shape, dtype=np.int64)
    is_geom = objtype == GEOM
    out[is_geom] = np.asarray(geom_labels)[objid[is_geom]]
    return out


def grid_model(n: int, side: int) -> object:
    """``n`` boxes in a ``side``-wide grid on the xy plane under a camera looking down."""
    boxes = "\n".join(
        f'<geom type="box" size="0.009 0.009 0.005" pos="{0.02 * (i % side) - 0.01 * side:.3f} '
        f'{0.02 * (i // side) - 0.01 * (n // side):.3f} 0"/>'
        for i in range(n)
    )
    xml = f"""<mujoco><visual><global offwidth="200" offheight="160"/></visual>
    <worldbody><camera name="{CAMERA_NAME}" pos="0 0 1"/>{boxes}</worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def render_grid(model, labels: np.ndarray):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with Renderer(Intrinsics(200, 160, 40.0)) as r:
        r.bind(model, labels)
        # looking down at the grid (a hair off the vertical, so look_at has an up direction)
        frame = r.render(data, look_at(np.array([0.0, -1e-3, 0.7]), np.zeros(3)))
        dtype = r.segmentation_dtype
    return frame, dtype, mujoco_labels(model, data, labels)


@pytest.mark.parametrize("seed", [0, 5])
def test_beopick_labels_equal_mujoco_segmentation(seed: int) -> None:
    import gymnasium as gym

    import beo_bench  # noqa: F401  (registers the ids)

    env = gym.make("BEOPick-v0", image_size=(160, 120), num_objects=4)
    obs, _ = env.reset(seed=seed)
    u = env.unwrapped
    ref = mujoco_labels(u.scene.model, u.scene.data, u.scene.geom_labels)
    env.close()
    seg = obs["segmentation"]
    assert seg.dtype == np.uint8
    np.testing.assert_array_equal(seg, ref)
    assert len(np.unique(seg)) >= 3  # table and at least two objects in view


def test_isolated_labels_equal_mujoco_segmentation() -> None:
    objects = ObjectSet("test")
    intr = Intrinsics(128, 128, 45.0)
    rng = np.random.default_rng(1)
    with IsolatedRenderer(intr) as iso, Renderer(intr, max_geom=1000) as r:
        for cat in objects.categories[:3]:
            inst = objects.get(cat, 0)
            model, data = build_isolated(inst, intr)
            labels = np.ones(model.ngeom, dtype=np.int32)
            r.bind(model, labels)
            T = OBJECT_RIG.sample(rng, np.zeros(3))
            frame = r.render(data, T)
            ref = mujoco_labels(model, data, labels)
            assert frame.segmentation.dtype == np.uint8
            np.testing.assert_array_equal(frame.segmentation, ref)
            view = iso.render(inst, T)
            np.testing.assert_array_equal(view.mask, (ref > 0) & (frame.depth > 0))
            np.testing.assert_array_equal(view.depth, frame.depth)
            assert view.mask.sum() > 100


def test_labels_of_geoms_beyond_255_in_the_scene_stay_uint8() -> None:
    model = grid_model(300, 20)
    labels = np.zeros(model.ngeom, dtype=np.int32)
    labels[[3, 255, 256, 299]] = [1, 2, 3, 254]  # scene geoms past one byte of ids
    frame, dtype, ref = render_grid(model, labels)
    assert dtype == np.uint8 and frame.segmentation.dtype == np.uint8
    np.testing.assert_array_equal(frame.segmentation, ref)
    assert set(np.unique(frame.segmentation).tolist()) == {0, 1, 2, 3, 254}


def test_many_labels_give_int32_and_the_same_depth() -> None:
    model = grid_model(300, 20)
    many = np.arange(1, 301, dtype=np.int32) * 7  # up to 2100: needs the green channel
    frame, dtype, ref = render_grid(model, many)
    assert dtype == np.int32 and frame.segmentation.dtype == np.int32
    np.testing.assert_array_equal(frame.segmentation, ref)
    assert len(np.unique(frame.segmentation)) > 250
    # drawing labels instead of geom ids changes no depth value
    few, _, _ = render_grid(model, np.zeros(model.ngeom, dtype=np.int32))
    np.testing.assert_array_equal(frame.depth, few.depth)
    assert (few.segmentation == 0).all() and (few.depth > 0).mean() > 0.3


def test_label_255_is_the_first_int32_label() -> None:
    model = grid_model(4, 2)
    for top, dtype in ((254, np.uint8), (255, np.int32)):
        labels = np.array([0, 1, 2, top], dtype=np.int32)
        frame, got, ref = render_grid(model, labels)
        assert got == dtype and frame.segmentation.dtype == dtype
        np.testing.assert_array_equal(frame.segmentation, ref)
        assert top in frame.segmentation


@pytest.mark.parametrize(
    ("labels", "match"),
    [
        (np.array([0, 1, -1, 2]), "0..16777214"),
        (np.array([0, 1, 2**24, 2]), "0..16777214"),
        (np.array([0, 1, 2]), r"\(4,\) integers"),
        (np.array([0.0, 1.0, 2.0, 3.0]), r"\(4,\) integers"),
    ],
)
def test_bad_geom_labels_are_refused(labels: np.ndarray, match: str) -> None:
    with Renderer(Intrinsics(200, 160, 40.0)) as r, pytest.raises(ValueError, match=match):
        r.bind(grid_model(4, 2), labels)
