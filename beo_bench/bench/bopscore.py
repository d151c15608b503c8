"""``beo-bench score --suite S --bop-results FILE.csv``: a BOP results file scored as a run.

A method that reads the BOP export of a suite (``beo-bench export``) and writes the BOP
challenge's results CSV is scored here on the very views the suite's runs score, into a
normal run directory (``run.json``, ``results.jsonl``, ``summary.json``): a leaderboard row
that ``compare`` and the gate pair with any other run of the suite, item by item.

- **Which estimate scores a view.** A view is one target (``test_targets_bop19.json``: the
  export lists the scored views). BOP's figures match the file's estimates as the BOP 2019
  evaluation does (:func:`beo_bench.bop.protocol.match_and_recall`: per image and object,
  the ``inst_count`` highest-scored estimates, matched greedily per threshold); a view's
  row holds its share of those matches (``bop_recall``), so the run's mean is BOP's average
  recall. Our own pose metrics (rotation, translation, MSSD, MSPD, NOCS accuracies and box
  IoU) take the highest-scored estimate of the view's object (with several instances, the
  estimates go by score to the instance nearest by MSSD).
- **What it cannot fill is left out.** A BOP method is told the object (its ``obj_id``),
  so a pose suite's run is in the ``class-given`` track and has no class figures; it
  estimates no shape or size, so its rows have no completion metrics and no size error
  (``pose_only``), and NOCS's box IoU uses the true model's box at the estimated pose.
- **A view without an estimate** is a failed view (``no estimate in the results file``),
  counted at its worst case in our means and as not found in BOP's recalls.
- **Time**: BOP's ``time`` is per image; a view gets its image's time over the image's
  targets (none where the file says -1).
- **Depth**: VSD compares with the depth as the export stores it (rounded to its PNG's
  step, :func:`as_exported`), the depth the method read: the toolkit's VSD on the export
  gives the same errors.

The scores depend on the suite's items, which the suite's seed fixes: the items are drawn
again here (the export is not read), so a results file written for an export made with
``--episodes N`` scores against the suite's first N items (``--episodes N`` here too).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from beo_bench.bench import rundir
from beo_bench.bench.export import image_of, object_ids, open_items
from beo_bench.bench.rows import rows_of
from beo_bench.bench.rundir import (
    RECORD_NAME,
    REPORT_NAME,
    RESULTS_NAME,
    SUMMARY_NAME,
    Summary,
    json_text,
)
from beo_bench.bench.runs import CorruptRunError, RunConfig, RunUsageError
from beo_bench.bench.scoring import base_row, bop_model, pose_metrics, score_bop, viewpoints
from beo_bench.bench.suites import Kind, Suite
from beo_bench.bop import protocol
from beo_bench.bop.results import BopEstimate, check_head, nearest_rotation, read_results
from beo_bench.errors import BeoBenchError, UsageError
from beo_bench.names import check_name
from beo_bench.types import Estimate, GroundTruth, View

NO_ESTIMATE = "no estimate in the results file"
"""A view's failure when the results file has no estimate of its object in its image."""


def check_method(name: str) -> str:
    """``name`` as a scored file's method name; a :class:`UsageError` for a name no row may
    take: an invalid one, or a backend's (``icp``, ``oracle``, ...: the file would stand on
    the leaderboard as that backend, a baseline or a bound)."""
    from beo_bench.backend import list_backends

    name = check_name(name, "method name (--method)")
    if name in list_backends():  # the in-tree ones, and any registered in this process
        raise UsageError(
            f"--method {name}: {name!r} is the name of a beo-bench backend, and a scored "
            f"file's row must not stand for it: pass --method {name}-bop (or another name of "
            "your method), or rename the file (its name up to the first _ is the default)"
        )
    return name


def method_name(path: Path) -> str:
    """The method a results file is named after: BOP names them ``METHOD_DATASET-SPLIT.csv``,
    so the part before the first ``_`` (the whole stem without one)."""
    return path.stem.split("_", 1)[0]


@dataclass
class _Target:
    """One scored view of an image: its truth and what the file's estimates did."""

    view: View
    gt: GroundTruth
    obj_id: int
    visib: float
    """Its visible fraction (BOP's ``visib_fract``): below ``visib_gt_min`` it is no
    target of BOP's matching."""
    best: BopEstimate | None = None
    shares: dict[str, float] | None = None


def as_exported(view: View, suite: Suite) -> View:
    """``view`` with its depth as the export stores it (rounded to the depth PNG's step,
    ``export.DEPTH_SCALES``): the depth the method read, and the toolkit's VSD would."""
    from dataclasses import replace

    from beo_bench.bench.export import DEPTH_SCALES

    step = DEPTH_SCALES[suite.kind] / 1000.0
    d = np.asarray(view.depth, dtype=np.float64)
    ok = np.isfinite(d) & (d > 0)
    q = np.where(ok, np.round(np.where(ok, d, 0.0) / step) * step, 0.0)
    return replace(view, depth=q.astype(np.asarray(view.depth).dtype))


def _estimate(e: BopEstimate, gt: GroundTruth) -> Estimate:
    """A BOP estimate as the scoring functions take it: its pose (``R`` as its nearest
    rotation: the file's is a rotation within ``ROTATION_TOL``, printed to a few decimals);
    the true size (a BOP method is given the model); no class or shape (never scored:
    ``pose_only``)."""
    return Estimate(
        class_probs=np.ones(1),
        rotation=nearest_rotation(e.R),
        translation=np.asarray(e.t_mm, dtype=np.float64) / 1000.0,
        size=np.asarray(gt.size, dtype=np.float64),
        shape=np.zeros((1, 1, 1)),
    )


def _errors(
    e: BopEstimate, view: View, gt: GroundTruth, suite: Suite
) -> tuple[np.ndarray, float, float]:
    """(VSD per tau, MSSD / diameter, MSPD brought to 640 px) of ``e`` against ``gt``."""
    fields = score_bop(_estimate(e, gt), gt, view, suite.dataset)
    diameter = fields["bop_diameter_mm"]
    px = fields["bop_mspd_px"]
    return (
        np.asarray(fields["bop_vsd"], dtype=np.float64),
        float(protocol.normalize_mssd(fields["bop_mssd_mm"], diameter)),
        np.inf if px is None else float(protocol.normalize_mspd(px, suite.image_size[0])),
    )


def _match(
    targets: list[_Target], ests: list[BopEstimate], suite: Suite, scene_id: int, im_id: int
) -> None:
    """Fill each target's BOP shares and best estimate from the estimates of its object
    (``targets`` share one image and obj_id)."""
    # our own metrics score every view, so they take as many estimates as there are views
    # (highest scored first, stable: file order on ties); BOP's matching keeps the inst_count
    # highest of them, inst_count being the views at least visib_gt_min visible (the
    # export's test_targets_bop19.json), and matches those to the visible ones
    ranked = sorted(ests, key=lambda e: -e.score)[: len(targets)]
    gts = [
        protocol.GtInstance(scene_id, im_id, j, t.obj_id, t.visib) for j, t in enumerate(targets)
    ]
    errs = [[_errors(e, t.view, t.gt, suite) for t in targets] for e in ranked]
    thresholds = {
        "vsd": protocol.VSD_THRESHOLDS,
        "mssd": protocol.MSSD_THRESHOLDS,
        "mspd": protocol.MSPD_THRESHOLDS_PX,
    }
    shares = {name: 0.0 for name in thresholds}
    if not any(t.visib >= protocol.VISIB_GT_MIN for t in targets):
        thresholds = {}  # no target: the views are left out of BOP's recalls (bop_visib_fract)
    for k, (name, th) in enumerate(thresholds.items()):
        estimates = [
            protocol.EstimateErrors(
                scene_id,
                im_id,
                targets[0].obj_id,
                e.score,
                {j: np.atleast_1d(errs[i][j][k]) for j in range(len(targets))},
            )
            for i, e in enumerate(ranked)
        ]
        rec = protocol.match_and_recall(gts, estimates, th)
        # found / (targets x thresholds): each visible target's share (a view below
        # visib_gt_min is left out of the mean by its bop_visib_fract, as out of rec's)
        shares[name] = rec.average
    free = list(range(len(ranked)))
    for j, t in enumerate(targets):  # our metrics: by score, each to its nearest instance
        t.shares = shares
        if free:
            i = min(free, key=lambda i: (errs[i][j][1], i))
            t.best = ranked[i]
            free.remove(i)


def _row(index: int, j: int, t: _Target, suite: Suite, image_targets: int) -> dict[str, Any]:
    row = base_row(index, j, t.view, t.gt, True)
    row["pose_only"] = True
    if t.best is None:
        row.update(score_bop(None, t.gt, t.view, suite.dataset))
        row.update(failure=NO_ESTIMATE, ms=None)
        return row
    e, gt = t.best, t.gt
    est = _estimate(e, gt)
    ms = None if e.time < 0 else 1000.0 * e.time / image_targets
    row.update(ms=ms, failure=None)
    # our pose metrics as a run scores them (the same model points: the pair compares),
    # without the size error: the estimate's size is the truth's, not the method's
    hull = bop_model(gt.key, suite.dataset).hull
    row.update(pose_metrics(est, gt, hull, t.view.K))
    del row["size_err_pct"]
    row.update(viewpoints(est, gt))
    row.update(score_bop(est, gt, t.view, suite.dataset))
    row["bop_recall"] = t.shares
    return row


def score_rows(
    suite: Suite, estimates: list[BopEstimate], ids: Any, items: Any, progress: bool = False
) -> list[dict[str, Any]]:
    """The result rows of ``estimates`` on ``suite``'s items (see the module docstring)."""
    from tqdm import tqdm

    by_image: dict[tuple[int, int, int], list[BopEstimate]] = {}
    for e in estimates:
        by_image.setdefault((e.scene_id, e.im_id, e.obj_id), []).append(e)
    rows: list[dict[str, Any]] = []
    for index in tqdm(
        range(suite.size), disable=None if progress else True, desc=f"score {suite.label}"
    ):
        scene_id, im_id = image_of(index)
        views = items.views(index)
        truths = items.truths(index, views)
        views = [as_exported(v, suite) for v in views]
        targets = [
            _Target(v, g, ids.ids[g.key], score_bop(None, g, v, suite.dataset)["bop_visib_fract"])
            for v, g in zip(views, truths, strict=True)
        ]
        groups: dict[int, list[_Target]] = {}
        for t in targets:
            groups.setdefault(t.obj_id, []).append(t)
        for obj_id, group in groups.items():
            ests = by_image.get((scene_id, im_id, obj_id), [])
            if ests:
                _match(group, ests, suite, scene_id, im_id)
        rows += [_row(index, j, t, suite, len(targets)) for j, t in enumerate(targets)]
    return rows


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _check_out(out: Path, record: dict[str, Any]) -> None:
    """Refuse an ``out`` (claimed and locked by the caller) that holds anything but an
    earlier score of the same method on the same suite: a ``run`` of a backend, another
    method's score, or results without a run record. Nothing in it is touched."""
    old = rundir.read_record(out / RECORD_NAME)  # a damaged or foreign one: CorruptRunError
    if old is None:
        held = [n for n in (RESULTS_NAME, SUMMARY_NAME) if (out / n).exists()]
        if held:
            raise CorruptRunError(
                f"--out {out} holds {', '.join(held)} but no {RECORD_NAME}, so what wrote them "
                "cannot be checked and they are not overwritten: choose another --out"
            )
        return
    if not old.get("bop_results"):
        raise RunUsageError(
            f"--out {out} holds a run of backend {old.get('backend')!r} (`beo-bench run`), "
            "not a scored results file: choose another --out (a score never replaces a run)"
        )
    mine = {k: record[k] for k in ("suite", "backend")}
    if {k: old.get(k) for k in mine} != mine:
        raise RunUsageError(
            f"--out {out} holds the score of method {old.get('backend')!r} on "
            f"{(old.get('suite') or {}).get('name')!r}, not of {record['backend']!r} on "
            f"{record['suite'].get('name')!r}: choose another --out"
        )


def score_results(
    suite: Suite,
    results: Path | str,
    out: Path | str,
    method: str | None = None,
    progress: bool = False,
) -> Summary:
    """Score the BOP results CSV ``results`` on ``suite`` into the run directory ``out``
    (new, empty, or an earlier score of the same method on the same suite: rewritten);
    returns the summary. The file is checked before ``out`` is made; then ``out`` is
    claimed (its marker) and locked (``run.lock``) as ``run`` does, and refused when it
    holds a ``run`` of a backend or another method's score (:func:`_check_out`)."""
    from beo_bench.bench.runner import machine_provenance
    from beo_bench.bench.summary import summarise
    from beo_bench.objects import LIBRARY_VERSION

    if suite.kind is Kind.PICK or not suite.protocol.scores_pose:
        raise UsageError(
            f"--suite {suite.name}: a BOP results file holds poses, and {suite.name} does not "
            "score poses (it gives them, or scores grasps): score it on a pose suite "
            "(pose-1dof, pose-3dof, ..., or tabletop: the pick suite's kind of scenes)"
        )
    path = Path(results)
    if not path.is_file():
        raise UsageError(f"--bop-results {path}: no such file: give the results CSV to score")
    name = check_method(method or method_name(path))
    check_head(path)  # a file broken near its top is refused before the suite is built
    if suite.class_hint:
        suite = suite.with_overrides(track="class-given")  # the object is given
    items = open_items(suite)
    try:
        ids = object_ids(suite, items)
        known_images = {image_of(i) for i in range(suite.size)}
        scope = (
            f"{suite.name}'s first {suite.size} items (score with the --episodes, --seed, "
            "--categories and --objects the export was made with)"
        )
        estimates = read_results(path, set(ids.info), known_images, scope)
        digest = _sha256(path)
        record = {
            **rundir.run_identity(RunConfig(suite, name, {}, False)),
            "model_digest": digest,
            "library_version": LIBRARY_VERSION,
            "uses_class_hint": False,
            "privileged": False,
            "bop_results": {"file": path.name, "sha256": digest, "estimates": len(estimates)},
        }
        out = rundir.open_run_dir(Path(out))
        with rundir.lock_run_dir(out):  # held from the check to the last write: one writer
            _check_out(out, record)
            rows = score_rows(suite, estimates, ids, items, progress)
            summary = summarise(
                suite,
                name,
                rows_of(rows),
                uses_class_hint=False,
                model_digest=digest,
                provenance={
                    **machine_provenance(),
                    "suite": suite.record(),
                    "backend_kwargs": {},
                    "bop_results": record["bop_results"],
                    "library_version": LIBRARY_VERSION,
                    "model_digest": digest,
                    "privileged": False,
                },
            )
            # every text made before any is written: a number JSON cannot hold stops the
            # score with the directory as it was
            try:
                texts = {
                    RECORD_NAME: json_text(record, allow_nan=False) + "\n",
                    RESULTS_NAME: "".join(json_text(r, None, False) + "\n" for r in rows),
                    SUMMARY_NAME: json_text(summary.to_json(), allow_nan=False) + "\n",
                }
            except ValueError as e:
                raise BeoBenchError(
                    f"{path}: a score came out as NaN or infinite ({e}), which JSON cannot "
                    f"hold; nothing was written to {out}: please report it with the file"
                ) from None
            (out / REPORT_NAME).unlink(missing_ok=True)  # an earlier score's: now stale
            for file_name, text in texts.items():
                rundir.write_text(out / file_name, text)
    finally:
        items.close()
    return summary
