"""Publishing an HBEO or HBEO-MDN network (``beo-bench publish hbeo|hbeo-mdn``): its arrays
in the published files' storage (:mod:`beo_bench.perception.published`, which knows no model).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from beo_bench.errors import UsageError
from beo_bench.perception.digest import state_digest
from beo_bench.perception.hbeo.model import HBEOModel
from beo_bench.perception.published import (
    INT8_MIN_SIZE,
    NET_PREFIX,
    PER_CATEGORY,
    PUBLISHED_DIR,
    SCALE,
    STORAGE,
    _state,
    per_category_stem,
    quantise,
    write,
)

__all__ = ["hbeo_arrays", "publish_hbeo"]


def hbeo_arrays(model: HBEOModel, storage: str = "float16") -> dict[str, np.ndarray]:
    """The arrays of an HBEO model's published file: the network's floating tensors in
    ``storage`` (``int8``: the weight tensors of :data:`INT8_MIN_SIZE` elements or more
    quantised, :func:`quantise`, the rest in float16), its integer buffers as they are, the
    standardisation in float32."""
    if storage not in STORAGE:
        raise ValueError(f"storage={storage!r}: one of {STORAGE}")
    out: dict[str, np.ndarray] = {}
    for k, v in model.net.state_dict().items():
        a = v.detach().cpu().numpy()
        if a.dtype != np.float32 or storage == "float32":
            out[NET_PREFIX + k] = a
        elif storage == "int8" and a.ndim >= 2 and a.size >= INT8_MIN_SIZE:
            out[NET_PREFIX + k], out[NET_PREFIX + k + SCALE] = quantise(a)
        else:
            out[NET_PREFIX + k] = a.astype(np.float16)
    out["coef_mean"] = np.asarray(model.coef_mean, np.float32)
    out["coef_std"] = np.asarray(model.coef_std, np.float32)
    return out


def publish_hbeo(
    model: HBEOModel,
    root: Path | None = None,
    storage: str = "float16",
    per_category: bool = False,
) -> str:
    """Publish ``model`` as ``<kind>`` or, with ``per_category`` (it is the
    ``per-category`` recipe's one-class network: ``hbeo.model.is_per_category_default``)
    of a class in :data:`PER_CATEGORY`, as :func:`per_category_stem` with its subspace."""

    if model.config.size != "small":
        raise UsageError(
            f"only the small networks are published (the published set stays under 20 MB); "
            f"this is a {model.config.size} one: keep it in the cache and load it with "
            "--opt model=NAME"
        )
    meta = model.stored_meta()
    meta["stored_dtype"] = storage

    arrays = hbeo_arrays(model, storage)
    # the digest is of the weights as used (float32 after widening): what a run records
    meta["digest"] = state_digest(_state(arrays))
    kind, cats = model.config.kind, model.categories
    if per_category:
        if cats[0] not in PER_CATEGORY:
            raise UsageError(
                f"only the per-category networks of {', '.join(PER_CATEGORY)} are published "
                f"(Tables 5.1/5.2); keep the {cats[0]} one in the cache"
            )
        # the one-class subspace it regresses, as trained (lossless: the network was
        # trained on these exact coefficients, and its fingerprint must match): 20-130 kB
        beo_stem = per_category_stem("beo", cats[0])
        write(beo_stem, model.beo.stored_meta(), model.beo.arrays(), root or PUBLISHED_DIR)
        return write(per_category_stem(kind, cats[0]), meta, arrays, root or PUBLISHED_DIR)
    return write(kind, meta, arrays, root or PUBLISHED_DIR)
