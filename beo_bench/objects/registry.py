"""The category registry and the deterministic procedural generator.

A category is one module with one decorated builder::

    @register_category("mug", params={...}, pickable=True, shapenet_synsets=("03797390",))
    def build(p: Params) -> Assembly: ...

An instance is fully determined by (category, split, index, LIBRARY_VERSION): its
parameters come from a ``numpy`` ``SeedSequence`` keyed by those four, so splits are
disjoint streams by construction and the same key always gives the same mesh.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trimesh

from beo_bench.errors import MeshError, UnknownCategoryError, UnknownSplitError
from beo_bench.objects.params import Params, ParamSpec, sample_params
from beo_bench.objects.primitives import Assembly
from beo_bench.objects.solid import check_solid
from beo_bench.types import ContinuousSymmetry, Symmetry

LIBRARY_VERSION = 2
"""Bump when any generator changes its output: it re-keys every procedural instance."""

SPLITS: tuple[str, ...] = ("train", "val", "test", "ood")
DEFAULT_SPLIT_SIZES: dict[str, int] = {"train": 200, "val": 20, "test": 50, "ood": 50}
"""Instances per category and split of the default library (``ObjectSet(per_category=...)``
changes it)."""

Builder = Callable[[Params], Assembly]


@dataclass(frozen=True)
class CategorySpec:
    """A registered procedural category."""

    name: str
    params: dict[str, ParamSpec]
    build: Builder
    pickable: bool = True
    """Meant to be picked by the 8 cm parallel gripper somewhere sensible."""
    shapenet_synsets: tuple[str, ...] = ()
    """ShapeNetCore synset ids that map to this category."""
    modelnet_names: tuple[str, ...] = ()
    """ModelNet class folder names that map to this category."""
    description: str = ""


_REGISTRY: dict[str, CategorySpec] = {}


def register_category(
    name: str,
    *,
    params: dict[str, ParamSpec],
    pickable: bool = True,
    shapenet_synsets: tuple[str, ...] = (),
    modelnet_names: tuple[str, ...] = (),
) -> Callable[[Builder], Builder]:
    """Register ``build`` as the generator of category ``name``."""

    def deco(build: Builder) -> Builder:
        if name in _REGISTRY:
            raise ValueError(f"category {name!r} is already registered")
        _REGISTRY[name] = CategorySpec(
            name=name,
            params=params,
            build=build,
            pickable=pickable,
            shapenet_synsets=shapenet_synsets,
            modelnet_names=modelnet_names,
            description=(build.__doc__ or "").strip(),
        )
        return build

    return deco


def categories() -> tuple[str, ...]:
    """Names of the registered procedural categories, sorted."""
    return tuple(sorted(_REGISTRY))


def pickable_categories() -> tuple[str, ...]:
    """The registered categories meant to be picked (BEOPick-v0's default target classes,
    the class list its scenes' views carry), sorted."""
    return tuple(c for c in categories() if _REGISTRY[c].pickable)


def get_category(name: str) -> CategorySpec:
    try:
        return _REGISTRY[name]
    except KeyError:
        raise UnknownCategoryError(
            f"unknown category {name!r}; known categories: {', '.join(categories())}"
        ) from None


def check_split(split: str) -> str:
    if split not in SPLITS:
        raise UnknownSplitError(f"unknown split {split!r}; use one of {', '.join(SPLITS)}")
    return split


def instance_rng(category: str, split: str, index: int) -> np.random.Generator:
    """The generator of one instance's parameters. crc32, unlike ``hash()``, is stable
    across processes and runs."""
    entropy = [
        LIBRARY_VERSION,
        zlib.crc32(category.encode()),
        SPLITS.index(check_split(split)),
        int(index),
    ]
    return np.random.default_rng(np.random.SeedSequence(entropy))


def instance_params(category: str, split: str, index: int) -> Params:
    """The shape parameters of instance ``index`` of ``category`` in ``split``."""
    spec = get_category(category)
    return sample_params(spec.params, instance_rng(category, split, index), ood=split == "ood")


@dataclass
class Generated:
    """A built instance in its canonical frame (bounding-box centre at the origin)."""

    mesh: trimesh.Trimesh
    parts: list[trimesh.Trimesh] | None
    """Exact convex parts, or None when the collision geometry must come from CoACD."""
    symmetry: Symmetry


def generate(category: str, params: Params) -> Generated:
    """Build, union and centre one instance."""
    asm = get_category(category).build(params)
    mesh = union(asm.parts)
    centre = mesh.bounds.mean(axis=0)
    mesh.apply_translation(-centre)
    parts = []
    for p in asm.parts:
        q = p.copy()
        q.apply_translation(-centre)
        parts.append(q)
    check_solid(mesh, f"{category} {params}")
    if mesh.body_count != 1:
        # Parts that fail to touch would make a "floating" object that falls apart in the
        # simulator's eyes (collision parts are welded to one body) - a generator bug.
        raise MeshError(
            f"{category} {params}: the parts form {mesh.body_count} separate solids; "
            "a generator must produce one connected object"
        )
    return Generated(mesh=mesh, parts=parts, symmetry=_shift_symmetry(asm.symmetry, -centre))


def union(parts: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """The solid union of watertight parts by manifold3d's batch boolean (called directly:
    trimesh's wrapper re-checks every part and costs 1.5x as much)."""
    import manifold3d as mf

    solids = [
        mf.Manifold(
            mf.Mesh(
                vert_properties=np.asarray(p.vertices, np.float32),
                tri_verts=np.asarray(p.faces, np.uint32),
            )
        )
        for p in parts
    ]
    out = mf.Manifold.batch_boolean(solids, mf.OpType.Add).to_mesh()
    return trimesh.Trimesh(
        np.asarray(out.vert_properties[:, :3], np.float64),
        np.asarray(out.tri_verts, np.int64),
        process=False,
    )


def _shift_symmetry(sym: Symmetry, shift: np.ndarray) -> Symmetry:
    """Express a symmetry group after translating the object by ``shift``."""
    T = np.eye(4)
    T[:3, 3] = shift
    Ti = np.linalg.inv(T)
    cont: list[ContinuousSymmetry] = [
        {"axis": c["axis"], "offset": (np.asarray(c["offset"]) + shift).round(9).tolist()}
        for c in sym["continuous"]
    ]
    disc = [(T @ np.asarray(D) @ Ti).round(9).tolist() for D in sym["discrete"]]
    return {"continuous": cont, "discrete": disc}
