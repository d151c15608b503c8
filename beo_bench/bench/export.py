"""``beo-bench export --suite S --format bop DIR``: a suite's items as a BOP dataset.

Every item is one BOP image (an isolated view; a tabletop or pick scene): its colour image,
its depth as the suite's sensor (or ``--sensor``) captures it, and each object's pose,
silhouette (``mask``: the true model rendered alone, ``beo_bench.bop.render``, joined with
its visible pixels) and visible pixels (``mask_visib``: the renderer's segmentation, the one
the views are cut from). Item ``i`` is image ``im_id = i % 1000`` of scene ``scene_id = i //
1000`` (:func:`image_of`), and the objects of an image are listed in the order of the item's
scored views (view ``j`` is ground truth ``j``), then its other objects (a tabletop object
with fewer than the suite's ``min_pixels``): a target list (``test_targets_bop19.json``)
names the scored views only (those at least ``visib_gt_min`` = 10% visible, as BOP's), so
a results file scores the very views a run does.

Object ids are given in the order instances first appear (the test items in order, then
the training items): the ids of a shorter export (``--episodes``) are those of the full one,
and ``beo-bench score`` finds them again from the suite alone (:func:`object_ids`). The
training split (``train/``) has ``--train-items`` items of the same protocol drawn from the
split's training instances, with another seed.

``--withhold-gt`` writes the test split as the BOP challenge ships one: images, cameras and
the targets, but no ``scene_gt.json``, ``scene_gt_info.json`` or masks (``beo-bench score``
never reads them: it draws the suite's items again). The export writes into its folder
through :func:`beo_bench.bop.files.export_dir`: one export at a time, never through a
symbolic link, and a re-export removes the files of the earlier one that it does not write
again (and only those: a file the user put or changed there stays).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from beo_bench.bench.kinds import get_kind
from beo_bench.bench.kinds.common import Items
from beo_bench.bench.suites import Kind, Suite
from beo_bench.objects import instance_from_key

IMAGES_PER_SCENE = 1000
"""Images per BOP scene folder: item ``i`` is image ``i % 1000`` of scene ``i // 1000``."""
TRAIN_SEED_OFFSET = 7_000_003
"""Added to a suite's seed for its training items: draws unrelated to its test items'."""


def image_of(item: int) -> tuple[int, int]:
    """``(scene_id, im_id)`` of item ``item``."""
    return item // IMAGES_PER_SCENE, item % IMAGES_PER_SCENE


@dataclass(frozen=True)
class ExportObject:
    """One object of an exported image."""

    key: str
    category: str
    R_cam: np.ndarray
    """(3, 3) model -> camera rotation (OpenCV axes)."""
    t_cam: np.ndarray
    """(3,) model -> camera translation, metres."""
    mask_visib: np.ndarray
    """(H, W) bool: its visible pixels."""
    view: int | None
    """The item's scored view that shows it (None: not scored, no target)."""


@dataclass(frozen=True)
class ExportImage:
    """One item as a BOP image."""

    item: int
    rgb: np.ndarray
    depth: np.ndarray
    """(H, W) metres as the sensor measures it; 0 = no return."""
    K: np.ndarray
    cam_to_world: np.ndarray
    objects: list[ExportObject]


def training_suite(suite: Suite, items: int) -> Suite:
    """The suite's protocol on ``items`` items of its split's training instances."""
    return replace(suite, split="train", seed=suite.seed + TRAIN_SEED_OFFSET, size=items)


def _isolated(items: Any, index: int) -> ExportImage:
    view = items.isolated_view_only(index)
    gt = items.isolated_truth(index)
    inst, T = items.scene(index)
    renderer = items.renderer
    ideal = renderer.render(inst, T, sensor="ideal")  # the silhouette, whatever the sensor
    obj = ExportObject(gt.key, gt.category, gt.R_cam, gt.t_cam, ideal.mask, 0)
    return ExportImage(
        index, renderer.render_rgb(inst, T), view.depth, view.K, view.cam_to_world, [obj]
    )


def _scene_objects(items: Any, min_pixels: int) -> tuple[list[Any], int]:
    """The objects of the env's scene in export order, and how many of them the item
    scores: its scored views' first (``min_pixels`` visible, as ``SceneItems`` cuts them),
    then the others."""
    states = items.env.ground_truth()
    scored = [g for g in states if g.pixels >= min_pixels]
    return scored + [g for g in states if g.pixels < min_pixels], len(scored)


def _scene(items: Any, index: int, min_pixels: int) -> ExportImage:
    obs = items.reset(index)
    seg = np.asarray(obs["segmentation"])
    states, n_scored = _scene_objects(items, min_pixels)
    objects = [
        ExportObject(
            g.key,
            g.category,
            np.asarray(g.R_cam),
            np.asarray(g.t_cam),
            seg == g.label,
            j if j < n_scored else None,
        )
        for j, g in enumerate(states)
    ]
    return ExportImage(
        index,
        items.env.rgb(),
        np.asarray(obs["depth"], dtype=np.float64),
        np.asarray(obs["intrinsics"], dtype=np.float64),
        np.asarray(obs["cam_to_world"], dtype=np.float64),
        objects,
    )


def open_items(suite: Suite) -> Items:
    """The suite's items (no class given: an export shows no backend anything)."""
    return get_kind(suite.kind).open(suite, False, None)


def images(suite: Suite, items: Items, indices: range) -> Iterator[ExportImage]:
    """The items ``indices`` of ``suite`` as BOP images."""
    for i in indices:
        if suite.kind is Kind.ISOLATED:
            yield _isolated(items, i)
        else:
            yield _scene(items, i, suite.min_pixels)


def scene_keys(suite: Suite, items: Items, index: int) -> list[tuple[str, str]]:
    """``(key, category)`` of each object of item ``index`` in export order, without
    rendering more than the item's own draw needs."""
    if suite.kind is Kind.ISOLATED:
        gt = items.isolated_truth(index)  # type: ignore[attr-defined]
        return [(gt.key, gt.category)]
    items.reset(index)  # type: ignore[attr-defined]
    return [(g.key, g.category) for g in _scene_objects(items, suite.min_pixels)[0]]


class ObjectIds:
    """Object ids in order of first appearance (see the module docstring), with each
    object's category and split."""

    def __init__(self) -> None:
        self.ids: dict[str, int] = {}
        self.info: dict[int, dict[str, str]] = {}

    def get(self, key: str, category: str, split: str) -> int:
        if key not in self.ids:
            obj_id = len(self.ids) + 1
            self.ids[key] = obj_id
            self.info[obj_id] = {"category": category, "split": split, "key": key}
        return self.ids[key]


def object_ids(suite: Suite, items: Items | None = None) -> ObjectIds:
    """The object ids of the suite's test items as its export numbers them."""
    own = items is None
    items = open_items(suite) if items is None else items
    try:
        ids = ObjectIds()
        for i in range(suite.size):
            for key, cat in scene_keys(suite, items, i):
                ids.get(key, cat, suite.split)
        return ids
    finally:
        if own:
            items.close()


# -- writing ---------------------------------------------------------------------------------
EXPORT_RECORD_NAME = "beo_bench_export.json"
"""beo-bench's record of an export (not a BOP file): the suite, sensor, item counts and
library version it was made from; written last, so a folder without it is unfinished."""
DEPTH_SCALES = {Kind.ISOLATED: 0.1, Kind.TABLETOP: 1.0, Kind.PICK: 1.0}
"""mm per depth unit of the exported depth PNGs, per item kind (BOP's own datasets use 0.1 to
1): an isolated object lies within 1.2 m, so 0.1 mm steps (up to 6.55 m); a tabletop scene's
far floor reaches beyond 6.55 m, so 1 mm steps (up to 65.5 m, as the BOP datasets of real
sensors)."""


@dataclass(frozen=True)
class ExportSummary:
    """What an export wrote."""

    root: Any
    images: dict[str, int]
    """Images per split folder (``test``, ``train``)."""
    objects: int
    targets: int
    removed: int = 0
    """Files of the earlier export in the folder that this one replaced by none."""
    kept: tuple[str, ...] = ()
    """Files of the earlier export this one did not write, left because they changed."""


def _w2c(cam_to_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    T = np.linalg.inv(np.asarray(cam_to_world, dtype=np.float64))
    return T[:3, :3], T[:3, 3]


def _write_split(
    root: Any,
    folder: str,
    suite: Suite,
    ids: ObjectIds,
    targets: list[Any] | None,
    progress: bool,
    withhold_gt: bool = False,
) -> int:
    """Write ``suite``'s items into ``ROOT/folder``; the scored views' targets go to
    ``targets`` (None: a training split has none). Returns the images written."""
    from tqdm import tqdm

    from beo_bench.bench.scoring import bop_model
    from beo_bench.bop.files import BopTarget
    from beo_bench.bop.protocol import VISIB_GT_MIN
    from beo_bench.bop.scenes import GtInstance, SceneWriter

    items = open_items(suite)
    writer: SceneWriter | None = None
    n = 0
    try:
        bar = tqdm(
            images(suite, items, range(suite.size)),
            total=suite.size,
            disable=None if progress else True,
            desc=f"export {suite.label} ({folder})",
            unit="image",
        )
        for img in bar:
            scene_id, im_id = image_of(img.item)
            if writer is None or writer.scene_id != scene_id:
                if writer is not None:
                    writer.close()
                writer = SceneWriter(
                    root,
                    folder,
                    scene_id,
                    depth_scale=DEPTH_SCALES[suite.kind],
                    withhold_gt=withhold_gt,
                )
            h, w = img.depth.shape
            gts: list[GtInstance] = []
            counts: dict[int, int] = {}
            for o in img.objects:
                obj_id = ids.get(o.key, o.category, suite.split)
                silhouette = bop_model(o.key, suite.dataset).renderer.depth(
                    o.R_cam, o.t_cam, img.K, w, h
                )
                # a visible pixel is part of the silhouette even where the renderer's raster
                # and the ray cast disagree on an edge pixel: mask_visib within mask
                full = (silhouette > 0) | o.mask_visib
                gts.append(GtInstance(obj_id, o.R_cam, o.t_cam, full, o.mask_visib))
                # a target is a scored view's object at least VISIB_GT_MIN visible (BOP 2019's
                # visib_gt_min; the same fraction scene_gt_info.json records)
                visib = int(np.count_nonzero(o.mask_visib)) / max(int(np.count_nonzero(full)), 1)
                if o.view is not None and visib >= VISIB_GT_MIN:
                    counts[obj_id] = counts.get(obj_id, 0) + 1
            R_w2c, t_w2c = _w2c(img.cam_to_world)
            writer.add_image(
                im_id, rgb=img.rgb, depth_m=img.depth, K=img.K, gts=gts, R_w2c=R_w2c, t_w2c_m=t_w2c
            )
            if targets is not None:
                targets += [BopTarget(scene_id, im_id, o, c) for o, c in sorted(counts.items())]
            n += 1
        if writer is not None:
            writer.close()
    finally:
        items.close()
    return n


def export_bop(
    suite: Suite,
    out: Any,
    train_items: int = 0,
    progress: bool = False,
    withhold_gt: bool = False,
) -> ExportSummary:
    """Write ``suite``'s items (test split) and ``train_items`` training items as a BOP
    dataset in ``out`` (a new or empty folder, or an earlier export's: see
    ``beo_bench.bop.files.export_dir``); the module docstring says what goes where.
    ``withhold_gt``: the test split without its ground truth (poses, masks)."""
    from beo_bench.bop.files import (
        ObjectEntry,
        model_info,
        model_path,
        write_category_map,
        write_model_ply,
        write_models_info,
        write_targets,
    )
    from beo_bench.bop.store import (
        CATEGORY_MAP_NAME,
        MODELS_DIR,
        MODELS_INFO_NAME,
        TARGETS_NAME,
        export_dir,
    )

    with export_dir(out, extra=(EXPORT_RECORD_NAME,)) as ledger:
        root = ledger.root
        record = root / EXPORT_RECORD_NAME
        # the files every export writes: refused before anything is written when not ours
        for name in (MODELS_INFO_NAME, CATEGORY_MAP_NAME):
            ledger.check(root / MODELS_DIR / name)
        ledger.check(root / TARGETS_NAME)
        ledger.check(record)
        if record.exists():
            # rewritten when complete: a folder without it is unfinished (a record that is
            # not ours is refused when the export comes to write it)
            ledger.remove(record)
        ids = ObjectIds()
        targets: list[Any] = []
        written = {"test": _write_split(root, "test", suite, ids, targets, progress, withhold_gt)}
        if train_items > 0:
            train = training_suite(suite, train_items)
            written["train"] = _write_split(root, "train", train, ids, None, progress)
        infos, entries = {}, {}
        for obj_id, info in ids.info.items():
            inst = instance_from_key(info["key"], suite.dataset)
            mesh = inst.mesh
            v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
            write_model_ply(model_path(root, obj_id), v, f)
            infos[obj_id] = model_info(v, inst.symmetry)
            entries[obj_id] = ObjectEntry(info["category"], info["split"], info["key"])
        write_models_info(root / MODELS_DIR / MODELS_INFO_NAME, infos)
        write_category_map(root / MODELS_DIR / CATEGORY_MAP_NAME, entries)
        write_targets(root / TARGETS_NAME, targets)
        meta = _record(suite, train_items, withhold_gt)
        removed, kept = ledger.finish()  # the earlier export's files this one did not write
        _store_record(record, meta)
        ledger.finish()  # the record listed
    return ExportSummary(root, written, len(ids.info), len(targets), removed, tuple(kept))


def _store_record(path: Any, meta: dict[str, Any]) -> None:
    import json

    from beo_bench.bop.store import write_file

    write_file(path, json.dumps(meta, indent=2, sort_keys=True) + "\n")


def _record(suite: Suite, train_items: int, withhold_gt: bool) -> dict[str, Any]:
    from beo_bench.objects import LIBRARY_VERSION

    return {
        "suite": suite.name,
        "suite_version": suite.version,
        "sensor": suite.sensor,
        "seed": suite.seed,
        "items": {"test": suite.size, "train": train_items},
        "image_size": list(suite.image_size),
        "depth_scale": DEPTH_SCALES[suite.kind],
        "library_version": LIBRARY_VERSION,
        "withhold_gt": withhold_gt,
        "images": "item i is image i % 1000 of scene i // 1000; ground truth j of an image is "
        "the item's scored view j (the targets); later ones are objects no view scores",
    }
