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
            from beo_bench.perception.beo_model import read_arrays

            # headers checked before unpacking: the digest reads the file before the model
            state: Any = read_arrays(path, json.loads((path / "config.json").read_text()))
        else:
            import torch

            state = torch.load(pt, map_location="cpu", weights_only=True)
    except Exception as e:  # a torn or corrupt file: zip, pickle and OS errors alike
        raise CheckpointError(
            f"{path}: unreadable model ({type(e).__name__}: {e}); delete it and retrain"
        ) from e
    return state_digest(state)
