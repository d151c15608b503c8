"""Versioned benchmark suites (docs/design.md "Benchmark runner and leaderboards").

A suite is a frozen dataclass in a registry: what is rendered (isolated instances or
BEOPick-v0 scenes), which protocol the backend is held to (what it is told), the split,
how many items, and the base seed. Item ``i`` of a suite is generated from
``SeedSequence([seed, i])`` alone, so any subset of items, in any order, on any worker,
gives the same views. Bump ``version`` whenever a change alters the generated items or the
scoring: results of different versions are never compared.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from enum import Enum
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.errors import BeoBenchError, UsageError
from beo_bench.objects.datasets import SHORT_CHARS
from beo_bench.objects.sets import MODELNET10

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset


class Kind(str, Enum):
    """What a suite's items are; each kind is a module of :mod:`beo_bench.bench.kinds`
    (its cases, views, scoring, failure rows and summary metrics)."""

    ISOLATED = "isolated"
    """One object at the origin, viewed from ``OBJECT_RIG``: one scored view per item."""
    TABLETOP = "tabletop"
    """A BEOPick-v0 scene: every object with ``min_pixels`` visible pixels is a view."""
    PICK = "pick"
    """A BEOPick-v0 episode: the grasp planned from the estimates is executed."""

    def __str__(self) -> str:
        return self.value


class Protocol(str, Enum):
    """What a backend is told besides the view (docs/benchmark.md, "What a backend is
    told"): each member's fields are that table's row."""

    reveals: str
    """In words, what the View reveals about the object (docs/benchmark.md's table)."""
    hides: str
    """In words, what stays hidden: what the suite scores."""
    pose_hint: bool
    """``View.pose_hint``: the true rotation, translation and size."""
    up_hint: bool
    """``View.up_hint``: the object's up axis in the camera frame (alone: with the pose
    given it is part of the pose)."""
    world_frame: str
    """What ``View.cam_to_world`` says: ``random`` (a random rigid frame: nothing),
    ``random-yaw`` (up is up: a random yaw and translation), or ``robot`` (the camera
    and the table plane in the robot's frame, as a real robot knows them)."""

    def __new__(
        cls,
        value: str,
        reveals: str,
        hides: str,
        pose_hint: bool,
        up_hint: bool,
        world_frame: str,
    ) -> Protocol:
        obj = str.__new__(cls, value)
        obj._value_ = value
        obj.reveals = reveals
        obj.hides = hides
        obj.pose_hint = pose_hint
        obj.up_hint = up_hint
        obj.world_frame = world_frame
        return obj

    KNOWN_POSE = (
        "known-pose",
        "the true pose and size",
        "the class",
        True,
        False,
        "random",
    )
    ONE_DOF = (
        "1dof",
        "the object's up axis",
        "the class, the rotation about the up axis, the translation",
        False,
        True,
        "random-yaw",
    )
    THREE_DOF = (
        "3dof",
        "nothing about the pose",
        "the class, the rotation, the translation",
        False,
        False,
        "random",
    )
    FREE = (
        "free",
        "the camera and the table plane in the robot's frame",
        "the class, each object's pose on the table",
        False,
        False,
        "robot",
    )

    @classmethod
    def of(cls, value: str) -> Protocol:
        """The protocol named ``value`` (``"1dof"``; a member is returned as it is)."""
        for p in cls:
            if p.value == value:
                return p
        raise UsageError(f"protocol {value!r}: use one of {', '.join(p.value for p in cls)}")

    @property
    def scores_pose(self) -> bool:
        """Whether pose errors are scored (not when the pose is given)."""
        return not self.pose_hint

    def __str__(self) -> str:
        return self.value


TRACKS: tuple[str, ...] = ("class-given", "class-free")
"""The two tracks of a suite that allows the class hint (``Suite.class_hint``): in
``class-given`` every backend that can use the true class (its spec's
``Capabilities.class_hint``) is told
it, as in the dissertation's pose comparisons (Figures 3.6 and 4.3); in ``class-free`` no
backend is. The hint belongs to the track, never to a backend's option, so two rows of one
table are always scored under the same rules."""
DEFAULT_TRACK = "class-free"

VIEWPOINTS: tuple[str, ...] = ("rig", "top-down")
"""Where an isolated suite's camera is (``Suite.viewpoint``)."""
"""The track a suite with tracks is run in unless one is asked for (``--track``)."""


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
    rotation about the vertical is unknown), ``3dof`` (nothing about the pose), ``free``
    (tabletop and pick: the camera and the table plane in the robot's frame, as a real
    robot knows them). An isolated view's world frame is a random rigid frame (a yaw and a
    translation in 1-DOF, a rotation and a translation otherwise: ``kinds.isolated.world_frame``),
    so ``cam_to_world`` reveals nothing the protocol does not (docs/benchmark.md, "What a
    backend is told"). ``size``: items (views
    for isolated suites, scenes or episodes otherwise). ``class_hint``: the suite is scored
    in two tracks (:data:`TRACKS`), and ``track`` says which one this is: in
    ``class-given`` a backend that can use the true class (``Capabilities.class_hint``) is given
    it (such rows are marked and left out of the class accuracy), in ``class-free`` none
    is; a suite with tracks defaults to :data:`DEFAULT_TRACK`. Suites that score
    classification (``known-pose``, ``tabletop``, ``pick``) have no track (``None``) and
    never give the class. The track is part of what identifies a run.
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
    sensor: str = "ideal"
    """The depth sensor the views are captured by (``beo_bench.scenes.sensors``: ``ideal``,
    ``kinect-v1``, ``d435``; docs/sensors.md). Part of what identifies a run: a run under
    another sensor than the registered suite's own (:attr:`default_sensor`) is named by it
    (:attr:`label`, ``runs.run_name``) and has its own sections of the suite's page."""
    resolution: int = 32
    class_hint: bool = False
    min_pixels: int = 50
    description: str = ""
    item_timeout_s: float = 60.0
    track: str | None = None
    categories: tuple[str, ...] | None = None
    """Isolated suites only: the classes its items are drawn from (None: every class of
    the split). Views then carry this class list."""
    viewpoint: str = "rig"
    """Isolated suites only: where the camera is. ``rig``: the dissertation's rendered-view
    distribution of section 4.3 (``scenes.camera.OBJECT_RIG``: full azimuth, elevation
    0-60 deg, small roll); ``top-down``: chapter 3's single view from straight above
    (section 3.3.2; ``scenes.camera.TOP_DOWN_RIG``), the object's yaw in the image uniform."""
    dataset: Dataset | None = None
    """The user's dataset the objects come from (``--objects``; None: the procedural
    library). Set by :meth:`with_dataset`, which also names the suite by the dataset's
    digest; its identity (digest and loading options, not its path) is part of the run's."""

    def __post_init__(self) -> None:
        # given as their names ("isolated", "3dof"): kept as the enums, which are strings
        object.__setattr__(self, "kind", Kind(self.kind))
        object.__setattr__(self, "protocol", Protocol.of(self.protocol))
        object.__setattr__(self, "sensor", suite_sensor(self.sensor, self.name))
        if self.split == "all" and self.dataset is None:
            raise UsageError(
                "split 'all' exists for a user dataset only (--objects ROOT); the procedural "
                "library has train, val, test and ood"
            )
        if self.categories is not None and self.kind is not Kind.ISOLATED:
            raise UsageError(
                f"suite {self.name!r}: a class subset (--categories) applies to isolated suites "
                "only; tabletop and pick scenes draw from every pickable class"
            )
        if self.viewpoint not in VIEWPOINTS:
            raise UsageError(
                f"suite {self.name!r}: viewpoint {self.viewpoint!r}: use one of "
                f"{', '.join(VIEWPOINTS)}"
            )
        if self.viewpoint != "rig" and self.kind is not Kind.ISOLATED:
            raise UsageError(f"suite {self.name!r}: a viewpoint applies to isolated suites only")
        if self.class_hint and self.track is None:
            # frozen: the default track is filled in once, here
            object.__setattr__(self, "track", DEFAULT_TRACK)
        if self.track is None:
            return
        if not self.class_hint:
            raise UsageError(
                f"suite {self.name!r} has no tracks (it never gives the class), so track "
                f"{self.track!r} does not apply: drop --track for this suite"
            )
        if self.track not in TRACKS:
            raise UsageError(
                f"track {self.track!r} of suite {self.name!r}: use one of {', '.join(TRACKS)}"
            )

    @property
    def tracks(self) -> tuple[str | None, ...]:
        """The tracks this suite is scored in (``(None,)`` for a suite without tracks)."""
        return TRACKS if self.class_hint else (None,)

    @property
    def label(self) -> str:
        """The suite, its track and, when it is not the suite's own, its sensor:
        ``pose-1dof@class-given``, ``known-pose``, ``pose-3dof@class-free~d435``,
        ``tabletop~ideal``."""
        where = f"{self.name}@{self.track}" if self.track else self.name
        return where + (f"~{self.sensor_tag}" if self.sensor_tag else "")

    @property
    def default_sensor(self) -> str:
        """The registered suite's own sensor (``ideal`` for a suite this package does not
        register)."""
        from beo_bench.scenes.sensors import DEFAULT_SENSOR

        base = SUITES.get(base_name(self.name))
        return base.sensor if base is not None else DEFAULT_SENSOR

    @property
    def sensor_tag(self) -> str | None:
        """The sensor when it is not the suite's own (what names the run), else None: runs
        at the suite's own sensor keep the names they always had."""
        return None if self.sensor == self.default_sensor else self.sensor

    def with_sensor(self, name: str | None) -> Suite:
        """The same items captured by the sensor ``name`` (``--sensor``; None keeps the
        suite's own). An unknown name is a :class:`~beo_bench.scenes.sensors.SensorError`
        (a usage error, exit status 2) with the closest names."""
        return self if name is None else replace(self, sensor=name)

    @property
    def gives_class(self) -> bool:
        """Whether this suite's views carry the true class (to backends that use it)."""
        return self.track == "class-given"

    def with_overrides(
        self, size: int | None = None, seed: int | None = None, track: str | None = None
    ) -> Suite:
        """The same protocol with another item count, base seed or track (``--episodes``,
        ``--seed``, ``--track``); ``None`` keeps the suite's own."""
        return replace(
            self,
            size=self.size if size is None else int(size),
            seed=self.seed if seed is None else int(seed),
            track=self.track if track is None else str(track),
        )

    def with_categories(self, names: Sequence[str]) -> Suite:
        """This suite's protocol on a subset of its classes (``--categories``: class and set
        names, :func:`beo_bench.objects.sets.resolve_categories`), named
        ``<suite>+<set>`` (``pose-3dof+modelnet10``) or ``<suite>+<c1>+<c2>``: its items,
        runs and leaderboard page are its own. Isolated suites only."""
        from beo_bench.objects.sets import resolve_categories, set_name

        cats = resolve_categories(names)
        if self.kind is not Kind.ISOLATED:
            raise UsageError(
                f"--categories applies to isolated suites only; {self.name!r} is a "
                f"{self.kind} suite, whose scenes draw from every pickable class"
            )
        if self.categories is not None and not set(cats) <= set(self.categories):
            raise UsageError(
                f"suite {self.name!r} holds the classes {', '.join(self.categories)}; "
                f"--categories may only choose among them, not {', '.join(cats)}"
            )
        label = set_name(cats) or "+".join(cats)
        return replace(self, name=f"{self.base_name}+{label}", categories=cats)

    def with_dataset(self, dataset: Dataset, split: str | None = None) -> Suite:
        """This suite's protocol on a user's dataset (and its ``split``; None keeps the
        suite's own), named ``<suite>.<digest8>``: results on other data, or on an
        edited copy of this dataset, never share its runs or leaderboard page."""
        return replace(
            self,
            name=f"{self.name}.{dataset.short}",
            dataset=dataset,
            split=self.split if split is None else split,
        )

    @property
    def base_name(self) -> str:
        """The registered suite this one is (its name without a dataset's digest)."""
        return base_name(self.name)

    def record(self) -> dict[str, Any]:
        """The suite as a JSON-able dict (``run.json``, ``summary.json``). Without a
        dataset it is exactly the fields' ``asdict`` minus ``dataset``, so runs on the
        built-in library keep the identity they had before datasets existed; with one,
        the dataset's identity (its root is where it lies, not what it is: the run's
        provenance records it). Under a sensor other than ``ideal``, the sensor model's
        version (``beo_bench.scenes.sensors.SENSOR_VERSIONS``)."""
        out = asdict(self)
        del out["dataset"]
        if self.dataset is not None:
            out["dataset"] = self.dataset.identity()
        if self.sensor != "ideal":  # the ideal render's runs keep the identity they had
            from beo_bench.scenes.sensors import SENSOR_VERSIONS

            out["sensor_version"] = SENSOR_VERSIONS[self.sensor]
        return out


def suite_sensor(name: Any, suite: str = "") -> str:
    """``name`` if it is a registered sensor (:data:`beo_bench.scenes.sensors.SENSORS`),
    else a :class:`~beo_bench.scenes.sensors.SensorError` naming the closest ones."""
    from beo_bench.scenes.sensors import SensorError, check_sensor_name

    if not isinstance(name, str):
        where = f"suite {suite!r}: " if suite else ""
        raise SensorError(f"{where}sensor={name!r}: give a sensor's name (--sensor NAME)")
    return check_sensor_name(name)


def record_sensor(record: dict[str, Any]) -> str:
    """The sensor a suite record (``Suite.record()``, a summary's ``provenance["suite"]``)
    names; a record made before sensors existed says ``noise``: ``false`` was the ideal
    render; ``true``, the old noise model, is no sensor's (a :class:`UsageError`)."""
    sensor = record.get("sensor")
    if isinstance(sensor, str):
        return sensor
    if record.get("noise"):
        raise UsageError(
            "a run recorded with the old noise model (noise: true, before sensors existed) "
            "matches no sensor: re-run it with --sensor into a new --out"
        )
    return "ideal"


def base_name(name: str) -> str:
    """``pose-3dof.1a2b3c4d`` -> ``pose-3dof``, ``pose-3dof+modelnet10`` -> ``pose-3dof``
    (a registered name is returned as is)."""
    head, plus, _ = name.partition("+")
    if plus and head in SUITES:
        return head
    head, dot, tail = name.rpartition(".")
    if (
        dot
        and head in SUITES
        and len(tail) == SHORT_CHARS
        and all(c in "0123456789abcdef" for c in tail)
    ):
        return head
    return name


def base_suite(name: str) -> Suite:
    """The registered suite a (possibly dataset-named) suite name stands for: what decides
    how its results are summarised and compared."""
    return get_suite(base_name(name))


SUITES: dict[str, Suite] = {
    s.name: s
    for s in (
        Suite(
            "known-pose",
            4,
            Kind.ISOLATED,
            Protocol.KNOWN_POSE,
            size=500,
            seed=1000,
            description="class + completion with the true pose and size given (Table 3.1)",
        ),
        Suite(
            "pose-1dof",
            4,
            Kind.ISOLATED,
            Protocol.ONE_DOF,
            size=500,
            seed=2000,
            class_hint=True,
            description="isolated instances; only the rotation about the vertical is unknown "
            "(section 3.3.2)",
        ),
        Suite(
            "pose-3dof",
            4,
            Kind.ISOLATED,
            Protocol.THREE_DOF,
            size=1000,
            seed=3000,
            class_hint=True,
            description="isolated instances over the dissertation's viewpoint distribution "
            "(full azimuth, elevation range, roll 99% within 25 deg; Tables 4.1, 5.1, 5.2)",
        ),
        Suite(
            "pose-3dof-percat",
            3,
            Kind.ISOLATED,
            Protocol.THREE_DOF,
            size=600,
            seed=7000,
            class_hint=True,
            categories=("airplane", "car", "sofa"),
            description="Tables 5.1/5.2's protocol: pose-3dof's viewpoints on the car, "
            "airplane and sofa test instances, where a network trained on one category "
            "(`per_category=true`, chosen by the class) meets the shared one",
        ),
        Suite(
            "pose-3dof-ood",
            4,
            Kind.ISOLATED,
            Protocol.THREE_DOF,
            size=550,
            seed=6000,
            split="ood",
            class_hint=True,
            description="pose-3dof on the ood split (every instance has at least one shape "
            "parameter outside the training range): how each method degrades",
        ),
        Suite(
            "modelnet10-known-pose",
            1,
            Kind.ISOLATED,
            Protocol.KNOWN_POSE,
            size=500,
            seed=8000,
            categories=MODELNET10,
            viewpoint="top-down",
            description="Table 3.1's protocol: the ModelNet10 classes from chapter 3's single "
            "top-down view (section 3.3.2), the true pose and size given; class and "
            "completion (Figure 3.4)",
        ),
        Suite(
            "modelnet10-1dof",
            1,
            Kind.ISOLATED,
            Protocol.ONE_DOF,
            size=500,
            seed=8100,
            class_hint=True,
            categories=MODELNET10,
            viewpoint="top-down",
            description="Table 3.1's 1-DOF row: the ModelNet10 classes from the top-down "
            "view at a random rotation about the vertical (Figure 3.7)",
        ),
        Suite(
            "modelnet10-3dof",
            1,
            Kind.ISOLATED,
            Protocol.THREE_DOF,
            size=500,
            seed=8200,
            class_hint=True,
            categories=MODELNET10,
            description="Table 4.1's 3-DOF row: the ModelNet10 classes over section 4.3's "
            "viewpoint distribution, nothing about the pose given (Figure 4.3); the "
            "headroom suite",
        ),
        Suite(
            "tabletop",
            5,
            Kind.TABLETOP,
            Protocol.FREE,
            size=200,
            seed=4000,
            image_size=(640, 480),
            sensor="kinect-v1",
            item_timeout_s=180.0,
            description="BEOPick-v0 scenes with 1-4 objects, clutter, occlusion, seen by a "
            "Kinect v1 (structured-light noise, shadows, dropout); every visible object is "
            "scored",
        ),
        # version 5: 500 episodes (100 before), episode i's target of class i mod C, so
        # that every class has 27-28 targets and two methods' rates differ by a margin the
        # page can tell (issue 47)
        Suite(
            "pick",
            5,
            Kind.PICK,
            Protocol.FREE,
            size=500,
            seed=5000,
            image_size=(640, 480),
            item_timeout_s=180.0,
            description="BEOPick-v0 episodes, the target classes balanced (episode i's of "
            "class i mod C): the estimate of the target-class object becomes a mesh "
            "(marching cubes, placed by pose and size), the planner's best grasp is executed",
        ),
    )
}


SMOKE_SIZES: dict[Kind, int] = {Kind.ISOLATED: 20, Kind.TABLETOP: 6, Kind.PICK: 8}
"""Items per suite of the ``smoke`` set, by item kind (so a suite added to :data:`SUITES`
is in the set without being listed): the sizes at which every suite, with a fast backend
(``oracle``, ``hbeo``), runs in under 90 s on 2 cores with a warm asset cache
(docs/benchmark.md, "A smoke set"; ``benchmarks/bench_smoke.py`` measures it). Enough to see
a backend that breaks, not a small regression: the interval table beside it says which
differences n items can tell."""

SUITE_SETS: dict[str, dict[str, int]] = {
    "smoke": {name: SMOKE_SIZES[s.kind] for name, s in sorted(SUITES.items())},
}
"""Named sets of suites for ``beo-bench all --suites NAME``: each suite with its number of
items (a suite's own size when it is named alone)."""


def expand_suites(names: Sequence[str]) -> dict[str, int | None]:
    """Suite and set names (``all --suites``) -> each suite with its number of items (None:
    the suite's own size), in the order given; a suite named twice keeps its last mention.
    An unknown name is an :class:`UnknownSuiteError` (a usage error) listing both."""
    out: dict[str, int | None] = {}
    for name in names:
        if name in SUITE_SETS:
            out.update(SUITE_SETS[name])
            continue
        try:
            get_suite(name)
        except UnknownSuiteError:
            raise UnknownSuiteError(
                f"unknown suite {name!r}; {_suite_hint(name)}the suites are {sorted(SUITES)} "
                f"and the suite sets {sorted(SUITE_SETS)}"
            ) from None
        out.pop(name, None)  # moved to where it was last named
        out[name] = None
    return out


def item_rng(suite: Suite, index: int) -> np.random.Generator:
    """The generator of item ``index``: depends on the suite's seed and the index only."""
    return np.random.default_rng(np.random.SeedSequence([suite.seed, index]))


def episode_seed(suite: Suite, index: int) -> int:
    """The BEOPick-v0 ``reset`` seed of item ``index`` of a tabletop or pick suite."""
    return int(item_rng(suite, index).integers(2**31))


def get_suite(name: str) -> Suite:
    """The registered suite ``name``, or a registered isolated suite restricted to classes
    and sets: ``pose-3dof+modelnet10``, ``known-pose+car+mug`` (:meth:`Suite.with_categories`)."""
    head, plus, tail = name.partition("+")
    if plus and head in SUITES and tail:
        return SUITES[head].with_categories(tail.split("+"))
    if name not in SUITES:
        raise UnknownSuiteError(
            f"unknown suite {name!r}; {_suite_hint(name)}the suites are {sorted(SUITES)}"
        )
    return SUITES[name]


def _suite_hint(name: str) -> str:
    """ "did you mean 'pose-3dof'? " for a misspelt suite, in any case, also before a class
    subset (``pose-3dfo+car`` -> ``pose-3dof+car``); "" when no suite is close."""
    from beo_bench.names import closest

    head, plus, tail = name.partition("+")
    match = closest(head if plus else name, SUITES)
    if match is None:
        return ""
    meant = match + plus + tail if plus else match
    return f"did you mean {meant!r}? "


def list_suites() -> list[str]:
    return sorted(SUITES)


def backend_tracks(
    suite: Suite, uses_class_hint: bool, needs_class_hint: bool = False
) -> tuple[str | None, ...]:
    """The tracks a backend is run in on ``suite``: both for a backend that can use the
    class hint, ``class-free`` only for one that cannot (its ``class-given`` run would score
    exactly the same; the leaderboard lists its class-free run in both tracks' tables),
    ``class-given`` only for one that cannot work without it (``needs_class_hint``, e.g.
    per-category networks), and ``(None,)`` on a suite without tracks."""
    if suite.track is None:
        return (None,)
    if needs_class_hint:
        return ("class-given",)
    return TRACKS if uses_class_hint else (DEFAULT_TRACK,)


def check_track(
    suite: Suite, backend: str, uses_class_hint: bool, needs_class_hint: bool = False
) -> None:
    """Refuse the ``class-given`` track for a backend that cannot use the hint (a
    :class:`UsageError` saying to run it class-free), and the ``class-free`` one (or a
    suite without tracks) for a backend that needs it."""
    if needs_class_hint and suite.track != "class-given":
        raise UsageError(
            f"backend {backend!r} needs the class hint (it chooses a per-category network by "
            f"it), which only the class-given track of a pose suite gives: run it with "
            f"--track class-given on a suite with tracks, not {suite.label}"
        )
    if suite.track == "class-given" and not uses_class_hint:
        raise UsageError(
            f"backend {backend!r} does not use the class hint (its spec's class_hint "
            "capability is none), so its "
            f"class-given run on {suite.name} would score exactly as its class-free one: run "
            "it with --track class-free (the leaderboard lists that run in both tracks)"
        )
