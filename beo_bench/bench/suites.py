"""Versioned benchmark suites (DESIGN.md "Benchmark runner and leaderboards").

A suite is a frozen dataclass in a registry: what is rendered (isolated instances or
BEOPick-v0 scenes), which protocol the backend is held to (what it is told), the split,
how many items, and the base seed. Item ``i`` of a suite is generated from
``SeedSequence([seed, i])`` alone, so any subset of items, in any order, on any worker,
gives the same views. Bump ``version`` whenever a change alters the generated items or the
scoring: results of different versions are never compared.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

from beo_bench.errors import BeoBenchError

Kind = Literal["isolated", "tabletop", "pick"]
Protocol = Literal["known-pose", "1dof", "3dof", "free"]


class UnknownSuiteError(BeoBenchError, KeyError):
    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True)
class Suite:
    """One benchmark suite.

    ``kind``: ``isolated`` (one object at the origin, views from ``OBJECT_RIG``),
    ``tabletop`` (BEOPick-v0 scenes; every object with at least ``min_pixels`` visible
    pixels is one scored view) or ``pick`` (BEOPick-v0 episodes executed with the grasp
    planned from the estimate). ``protocol``: what the backend is told besides the view:
    ``known-pose`` (the true pose and size), ``1dof`` (the object's up axis: only the
    rotation about the vertical is unknown), ``3dof`` (nothing; the world frame is
    randomised so ``cam_to_world`` does not reveal the object's up), ``free`` (tabletop: the
    table's up is known from ``cam_to_world``, as for a real robot). ``size``: items (views
    for isolated suites, scenes or episodes otherwise). ``class_hint``: a backend that asks
    for the true class (``wants_class_hint``, the dissertation's ICP protocol) is given it;
    such rows are marked and left out of the class accuracy. Suites that score
    classification (``known-pose``, ``tabletop``, ``pick``) never give it.
    ``item_timeout_s``: how long one item may take in a worker before it is recorded as a
    failure (``timeout after S s``) and the worker replaced (``--item-timeout`` changes it
    for a run). The defaults are 20-30 times the slowest in-tree backend's item, measured
    with ``beo`` on a loaded 2-core machine: about 2 s an isolated item, 9 s a tabletop scene
    (3 views), 6 s a pick episode. Like ``size`` and ``description``, it changes no score,
    so it is not part of what identifies a run.
    """

    name: str
    version: int
    kind: Kind
    protocol: Protocol
    size: int
    seed: int
    split: str = "test"
    image_size: tuple[int, int] = (128, 128)
    fovy_deg: float = 45.0
    noise: bool = False
    resolution: int = 32
    class_hint: bool = False
    min_pixels: int = 50
    description: str = ""
    item_timeout_s: float = 60.0

    def with_overrides(self, size: int | None = None, seed: int | None = None) -> Suite:
        """The same protocol with another item count or base seed (``--episodes``,
        ``--seed``)."""
        return replace(
            self,
            size=self.size if size is None else int(size),
            seed=self.seed if seed is None else int(seed),
        )


SUITES: dict[str, Suite] = {
    s.name: s
    for s in (
        Suite(
            "known-pose",
            1,
            "isolated",
            "known-pose",
            size=500,
            seed=1000,
            description="class + completion with the true pose and size given (Table 3.1)",
        ),
        Suite(
            "pose-1dof",
            1,
            "isolated",
            "1dof",
            size=500,
            seed=2000,
            class_hint=True,
            description="isolated instances; only the rotation about the vertical is unknown "
            "(section 3.3.2)",
        ),
        Suite(
            "pose-3dof",
            1,
            "isolated",
            "3dof",
            size=1000,
            seed=3000,
            class_hint=True,
            description="isolated instances over the dissertation's viewpoint distribution "
            "(full azimuth, elevation range, roll 99% within 25 deg; Tables 4.1, 5.1, 5.2)",
        ),
        Suite(
            "pose-3dof-ood",
            1,
            "isolated",
            "3dof",
            size=550,
            seed=6000,
            split="ood",
            class_hint=True,
            description="pose-3dof on the ood split (every instance has at least one shape "
            "parameter outside the training range): how each method degrades",
        ),
        Suite(
            "tabletop",
            1,
            "tabletop",
            "free",
            size=200,
            seed=4000,
            image_size=(640, 480),
            noise=True,
            item_timeout_s=180.0,
            description="BEOPick-v0 scenes with 1-4 objects, clutter, occlusion and sensor "
            "noise; every visible object is scored",
        ),
        Suite(
            "pick",
            1,
            "pick",
            "free",
            size=100,
            seed=5000,
            image_size=(640, 480),
            item_timeout_s=180.0,
            description="BEOPick-v0 episodes: the estimate of the target-class object becomes a "
            "mesh (marching cubes, placed by pose and size), the planner's best grasp is "
            "executed",
        ),
    )
}


def get_suite(name: str) -> Suite:
    if name not in SUITES:
        raise UnknownSuiteError(f"unknown suite {name!r}; the suites are {sorted(SUITES)}")
    return SUITES[name]


def list_suites() -> list[str]:
    return sorted(SUITES)
