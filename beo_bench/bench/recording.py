"""``beo-bench run --rerun FILE``: a rerun recording of a run's first views.

Each logged view is a timeline step: the depth image with the object's mask, the true mesh
and the estimated shape (marching cubes of the estimate, placed by its pose and size), both
in the camera frame, and the per-view errors as text. Re-generated in the main process after
the run (items are deterministic, so this shows exactly what was scored).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from beo_bench.atomic import atomic_path
from beo_bench.bench.runs import RunContext
from beo_bench.errors import BeoBenchError


def log_run(ctx: RunContext, path: Path | str, items: int = 20) -> Path:
    """A rerun recording of the first ``items`` items of the run ``ctx`` at ``path``."""
    try:
        import rerun as rr
    except ImportError as e:
        raise BeoBenchError("--rerun needs rerun-sdk: pip install 'beo-bench[viz]'") from e
    from beo_bench.bench.evaluate import Evaluator
    from beo_bench.bench.scoring import estimate_mesh
    from beo_bench.objects import instance_from_key
    from beo_bench.sceneview import rerun_mesh

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:  # a failed run leaves no partial recording at path
        rec = rr.RecordingStream("beo-bench-run")
        rec.save(tmp)
        ev = Evaluator(ctx)
        step = 0
        try:
            for index in range(min(items, ctx.suite.size)):
                views = ev.items.views(index)
                answers = [ev.predict(index, j, v) for j, v in enumerate(views)]
                for view, gt, (est, _, failure) in zip(
                    views, ev.items.truths(index, views), answers, strict=True
                ):
                    rec.set_time("view", sequence=step)
                    step += 1
                    h, w = view.depth.shape
                    rec.log("camera", rr.Pinhole(image_from_camera=view.K, width=w, height=h))
                    rec.log("camera/depth", rr.DepthImage(view.depth, meter=1.0))
                    rec.log("camera/mask", rr.SegmentationImage(view.mask.astype(np.uint8)))
                    truth = instance_from_key(gt.key, ctx.dataset).mesh.copy()
                    T = np.eye(4)
                    T[:3, :3], T[:3, 3] = gt.R_cam, gt.t_cam
                    truth.apply_transform(T)
                    rec.log("camera/truth", rerun_mesh(truth, [60, 180, 75, 160]))
                    mesh = estimate_mesh(est, np.eye(4)) if est is not None else None
                    if mesh is not None:
                        rec.log("camera/estimate", rerun_mesh(mesh, [230, 25, 75, 160]))
                    else:
                        rec.log("camera/estimate", rr.Clear(recursive=False))
                    text = f"{gt.key} ({gt.category})"
                    if est is not None:
                        text += f"; predicted {view.categories[est.class_index]}"
                    if failure:
                        text += f"; FAILED: {failure}"
                    rec.log("info", rr.TextLog(text))
        finally:
            ev.close()
            rec.flush()
            rec.disconnect()
    return path
