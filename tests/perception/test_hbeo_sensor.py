"""HBEO's training crops through a depth sensor (``DatasetConfig.sensor``, ``train
--sensor``): None is the published recipe, its shards' digest and the model's config as
they were before sensors existed; a sensor captures the noisy share of the crops."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict

import numpy as np
import pytest

from beo_bench.objects import LIBRARY_VERSION
from beo_bench.perception.hbeo.data import DATA_VERSION, DatasetConfig, Shard, render_shard
from beo_bench.perception.hbeo.model import default_config, default_name
from beo_bench.scenes.sensors import SensorError
from beo_bench.training import TrainRequest, hbeo_config

CATS = ("mug", "bowl")


def _digest_before_sensors(cfg: DatasetConfig) -> str:
    """``DatasetConfig.digest`` as it was written before the field existed."""
    fields = {k: v for k, v in asdict(cfg).items() if k not in ("images", "val_images")}
    del fields["objects"], fields["sensor"]
    key = json.dumps([fields, DATA_VERSION, LIBRARY_VERSION], sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:12]


def test_no_sensor_is_the_published_recipe_and_a_sensor_names_its_own_shards() -> None:
    plain = DatasetConfig(categories=CATS)
    assert plain.digest() == _digest_before_sensors(plain)
    kinect = DatasetConfig(categories=CATS, sensor="kinect-v1")
    assert kinect.digest() != plain.digest()
    with pytest.raises(SensorError, match="did you mean 'kinect-v1'"):
        DatasetConfig(categories=CATS, sensor="kinect")
    # the model's stored config and default name leave the unset sensor out
    cfg = default_config("hbeo", CATS)
    assert "sensor" not in cfg.to_json()["dataset"]
    sensed = hbeo_config(TrainRequest(categories=CATS, sensor="kinect-v1"), "hbeo")
    assert sensed.dataset.sensor == "kinect-v1" and sensed.to_json()["dataset"]["sensor"]
    assert default_name(sensed) != default_name(hbeo_config(TrainRequest(categories=CATS), "hbeo"))


@pytest.mark.parametrize(("kind", "index"), [("isolated", 1), ("tabletop", 0)])
def test_a_sensor_captures_the_noisy_share_of_the_crops(tmp_path, kind, index) -> None:
    shards = {}
    for name, sensor, share in (
        ("plain", None, 1.0),
        ("kinect", "kinect-v1", 1.0),
        ("again", "kinect-v1", 1.0),
        ("ideal", "kinect-v1", 0.0),
    ):
        cfg = DatasetConfig(categories=CATS, sensor=sensor, noise_share=share)
        render_shard(cfg, "train", index, kind, 4, tmp_path / f"{name}.npz")
        shards[name] = Shard.load(tmp_path / f"{name}.npz")
    kinect, ideal = shards["kinect"], shards["ideal"]
    assert kinect.noisy.all() and len(kinect) == 4 and not ideal.noisy.any()
    # shard i is SeedSequence(seed, i)'s: the same crops again
    np.testing.assert_array_equal(kinect.depth, shards["again"].depth)
    # the first crop is the same object from the same camera, captured by the sensor or not
    assert kinect.keys[0] == ideal.keys[0] and kinect.label[0] == ideal.label[0]
    assert not np.array_equal(kinect.depth[0], ideal.depth[0], equal_nan=True)
    # nor is the sensor the DepthNoise augmentation
    assert not np.array_equal(kinect.depth, shards["plain"].depth, equal_nan=True)
