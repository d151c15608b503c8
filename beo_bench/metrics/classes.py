"""Class metrics [Burchfiel]: accuracy, per-class accuracy, the confusion matrix, the
entropy of class probabilities and the entropy-thresholded "unknown" (conventions and
references: :mod:`beo_bench.metrics`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from beo_bench.metrics._arrays import _labels


def class_accuracy(pred: ArrayLike, true: ArrayLike) -> float:
    """Fraction of ``pred == true`` (an "unknown" prediction, -1, counts as wrong)."""
    p, t = _labels(pred, "pred"), _labels(true, "true")
    if p.shape != t.shape:
        raise ValueError(f"pred and true must have equal lengths, got {p.size} and {t.size}")
    return float(np.mean(p == t)) if p.size else float("nan")


def per_class_accuracy(pred: ArrayLike, true: ArrayLike, n_classes: int) -> NDArray[np.float64]:
    """(n_classes,) accuracy over the views of each true class (recall); NaN for a class
    that has no views."""
    p, t = _labels(pred, "pred"), _labels(true, "true")
    if p.shape != t.shape:
        raise ValueError(f"pred and true must have equal lengths, got {p.size} and {t.size}")
    if t.size and (t.min() < 0 or t.max() >= n_classes):
        raise ValueError(f"true labels must be in [0, {n_classes}), got {sorted(set(t.tolist()))}")
    count = np.bincount(t, minlength=n_classes).astype(np.float64)
    hit = np.bincount(t[p == t], minlength=n_classes).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, hit / np.maximum(count, 1), np.nan)


def confusion_matrix(
    pred: ArrayLike, true: ArrayLike, n_classes: int, unknown: bool = False
) -> NDArray[np.int64]:
    """Counts with rows = true class, columns = predicted class, (n_classes, n_classes).

    With ``unknown=True`` the matrix has one extra last column counting "unknown" (-1)
    predictions (see :func:`predict_with_unknown`); otherwise a -1 raises ``ValueError``.
    """
    p, t = _labels(pred, "pred"), _labels(true, "true")
    if p.shape != t.shape:
        raise ValueError(f"pred and true must have equal lengths, got {p.size} and {t.size}")
    if t.size and (t.min() < 0 or t.max() >= n_classes):
        raise ValueError(f"true labels must be in [0, {n_classes}), got {sorted(set(t.tolist()))}")
    lo = -1 if unknown else 0
    if p.size and (p.min() < lo or p.max() >= n_classes):
        raise ValueError(
            f"pred labels must be in [{lo}, {n_classes}) (unknown={unknown}), "
            f"got {sorted(set(p.tolist()))}"
        )
    cols = n_classes + 1 if unknown else n_classes
    p = np.where(p < 0, n_classes, p)
    M = np.zeros((n_classes, cols), dtype=np.int64)
    np.add.at(M, (t, p), 1)
    return M


def _probs(probs: ArrayLike) -> np.ndarray:
    P = np.asarray(probs, dtype=np.float64)
    if P.ndim not in (1, 2) or P.shape[-1] == 0:
        raise ValueError(f"probs must be (C,) or (N, C) class probabilities, got {P.shape}")
    if not np.isfinite(P).all() or (P < 0).any():
        raise ValueError("probs must be finite and non-negative")
    s = P.sum(axis=-1, keepdims=True)
    if (s <= 0).any():
        raise ValueError("probs must not sum to 0")
    return P / s


def entropy(probs: ArrayLike) -> float | NDArray[np.float64]:
    """Shannon entropy in nats, ``-sum p log p`` (0 log 0 = 0), of (C,) probabilities (a
    float) or of each row of (N, C) (an (N,) array). Rows are normalised to sum 1 first."""
    P = _probs(probs)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(P > 0, -P * np.log(np.where(P > 0, P, 1.0)), 0.0)
    H = terms.sum(axis=-1)
    return float(H) if H.ndim == 0 else H


def predict_with_unknown(probs: ArrayLike, threshold: float) -> int | NDArray[np.int64]:
    """The argmax class, or -1 ("unknown") when the entropy (nats) exceeds ``threshold``
    ([Burchfiel] section 6.2.4). (C,) -> int; (N, C) -> (N,) int array. The maximum entropy
    of C classes is ``log C``."""
    P = _probs(probs)
    H = np.asarray(entropy(P))
    cls = np.where(H > threshold, -1, np.argmax(P, axis=-1)).astype(np.int64)
    return int(cls) if cls.ndim == 0 else cls
