"""Shape-parameter distributions of the procedural categories.

Each category declares a dict of named parameter specs. In-distribution splits (``train``,
``val``, ``test``) draw from the nominal ranges; the ``ood`` split draws from wider ranges
and keeps only draws with at least one continuous parameter outside its nominal range, so
every ``ood`` instance is out of the training distribution by construction.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

ParamValue = float | int | bool | str
Params = dict[str, ParamValue]


@dataclass(frozen=True)
class Uniform:
    """A real parameter, uniform on [lo, hi]; on ``ood`` uniform on ``ood`` (default: the
    range widened by ``widen`` of its width on each side, clipped at ``floor``)."""

    lo: float
    hi: float
    ood: tuple[float, float] | None = None
    widen: float = 0.35
    floor: float | None = None

    def ood_range(self) -> tuple[float, float]:
        if self.ood is not None:
            return self.ood
        w = (self.hi - self.lo) * self.widen
        lo = self.lo - w
        floor = self.floor if self.floor is not None else (0.0 if self.lo >= 0 else None)
        if floor is not None:
            lo = max(lo, floor + 0.5 * (self.lo - floor))
        return lo, self.hi + w

    def sample(self, rng: np.random.Generator, ood: bool) -> float:
        lo, hi = self.ood_range() if ood else (self.lo, self.hi)
        return float(rng.uniform(lo, hi))

    def nominal(self, value: Any) -> bool:
        return bool(self.lo <= value <= self.hi)


@dataclass(frozen=True)
class Integer:
    """An integer parameter, uniform on {lo..hi}; ``ood`` gives the wider set."""

    lo: int
    hi: int
    ood: tuple[int, int] | None = None

    def sample(self, rng: np.random.Generator, ood: bool) -> int:
        lo, hi = self.ood if (ood and self.ood) else (self.lo, self.hi)
        return int(rng.integers(lo, hi + 1))

    def nominal(self, value: Any) -> bool:
        return bool(self.lo <= value <= self.hi)


@dataclass(frozen=True)
class Flag:
    """A part's presence: True with probability ``p`` (the same on ``ood``)."""

    p: float = 0.5

    def sample(self, rng: np.random.Generator, ood: bool) -> bool:
        return bool(rng.random() < self.p)

    def nominal(self, value: Any) -> bool:
        return True


@dataclass(frozen=True)
class Choice:
    """One of ``options`` (strings), with optional probabilities."""

    options: tuple[str, ...]
    p: tuple[float, ...] | None = None

    def sample(self, rng: np.random.Generator, ood: bool) -> str:
        return str(rng.choice(list(self.options), p=self.p))

    def nominal(self, value: Any) -> bool:
        return True


ParamSpec = Uniform | Integer | Flag | Choice


def sample_params(
    specs: dict[str, ParamSpec], rng: np.random.Generator, ood: bool, max_tries: int = 1000
) -> Params:
    """Draw one parameter set. Specs are drawn in declaration order, so adding a parameter
    at the end of a category's dict keeps earlier draws (bump the library version anyway)."""
    for _ in range(max_tries):
        params: Params = {name: spec.sample(rng, ood) for name, spec in specs.items()}
        if not ood or not all(spec.nominal(params[name]) for name, spec in specs.items()):
            return params
    raise RuntimeError("could not draw an out-of-distribution parameter set")
