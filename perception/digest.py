"""A digest of a trained model's contents, to check that a retrained default model is
bitwise the published one (``beo-bench cache info`` prints it for every cached model).

It hashes array names, dtypes, shapes and bytes, not the files: a zip or pickle header can
differ between two saves of equal arrays.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from beo_bench.errors import CheckpointError


def _arrays(state: Any, prefix: str = "") -> Iterator[tuple[str, np.ndarray]]:
    """The arrays in a nested dict of tensors or arrays, as (dotted name, array)."""
    if isinstance(state, dict):
        for k in sorted(state):
            yield from _arrays(state[k], f"{prefix}{k}.")
    elif hasattr(state, "detach"):  # a torch tensor
        yield prefix[:-1], state.detach().cpu().numpy()
    elif isinstance(state, np.ndarray):
        yield prefix[:-1], state


def state_digest(state: Any) -> str:
    """The first 16 hex digits of SHA-256 over the arrays of ``state`` (a nested dict of
    tensors or arrays): their dotted names, dtypes, shapes and bytes, in name order."""
    h = hashlib.sha256()
    for name, a in _arrays(state):
        a = np.ascontiguousarray(a)
        h.update(f"{name}:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def model_digest(path: Path) -> str:
    """:func:`state_digest` of the model directory ``path`` (``arrays.npz`` of a BEO model,
    ``weights.pt`` of an HBEO model). Raises :class:`CheckpointError` for a directory
    without a model or with a torn, empty or corrupt one."""
    path = Path(path)
    npz, pt = path / "arrays.npz", path / "weights.pt"
    if not npz.exists() and not pt.exists():
        raise CheckpointError(f"{path} holds no model (no arrays.npz or weights.pt)")
    try:
        if npz.exists():
            # headers checked before unpacking: the digest reads the file before the model
            state: Any = read_beo_arrays(path, json.loads((path / "config.json").read_text()))
        else:
            import torch

            state = torch.load(pt, map_location="cpu", weights_only=True)
    except Exception as e:  # a torn or corrupt file: zip, pickle and OS errors alike
        raise CheckpointError(
            f"{path}: unreadable model ({type(e).__name__}: {e}); delete it and retrain"
        ) from e
    return state_digest(state)


# -- a BEO model's arrays (here, below beo_model, which imports them: the digest of a model
# directory reads them without importing the model module) ---------------------------------
BEO_ARRAYS = ("basis", "mean", "class_mean", "class_cov", "class_size", "components", "shrinkage")
"""The arrays of a BEO model's ``arrays.npz``."""


def beo_array_shapes(meta: Any) -> dict[str, tuple[int, ...]] | None:
    """The shape of each BEO array that ``config.json`` (``meta``) implies, None when it does
    not say (no categories, resolution or k)."""
    try:
        C, D, k = len(meta["config"]["categories"]), int(meta["config"]["resolution"]), meta["k"]
        k = int(k)
    except (KeyError, TypeError, ValueError):
        return None
    return {
        "basis": (D**3, k),
        "mean": (D**3,),
        "class_mean": (C, k),
        "class_cov": (C, k, k),
        "class_size": (C, 3),
        "components": (C,),
        "shrinkage": (C, 2),
    }


def read_beo_arrays(path: Path, meta: Any) -> dict[str, np.ndarray]:
    """The arrays of the BEO model directory ``path``'s ``arrays.npz``, each member's header
    checked against the names, real dtypes and shapes its ``config.json`` (``meta``)
    declares before it is unpacked (:func:`beo_bench.safe_npz.read_npz`): a tampered file
    cannot make the reader unpack gigabytes. :class:`~beo_bench.safe_npz.UnsafeArrayError`
    otherwise."""
    from beo_bench.safe_npz import UnsafeArrayError, read_npz

    want = beo_array_shapes(meta)
    if want is None:
        raise UnsafeArrayError("config.json lacks categories, resolution or k")
    budget = 8 * sum(int(np.prod(s)) for s in want.values())  # float64 at most
    return read_npz(path / "arrays.npz", budget=budget, kinds="fiu", shapes=want, names=BEO_ARRAYS)
