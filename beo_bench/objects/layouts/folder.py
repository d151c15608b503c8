"""A folder with one sub-folder per category holding mesh files, searched recursively:
``<root>/<category>/**/<name>.{obj,off,ply,stl,glb,gltf}``
(:data:`~beo_bench.objects.meshfile.MESH_SUFFIXES`).

The sub-folder name is the category name. The files' axes are an option (``up``,
``front``; default ours) and their units are real (default units ``auto``: detected).
Splits: a stable hash of the path relative to the root. The search never follows a link out
of the root and is bounded (:mod:`beo_bench.objects.walk`).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path

from beo_bench.objects.dataset_load import Entry, LoadOptions, hash_split
from beo_bench.objects.meshfile import MESH_SUFFIXES, axes_rotation
from beo_bench.objects.walk import walk_files
from beo_bench.types import Mat3


def mesh_files(folder: Path, root: Path | None = None) -> Iterator[Path]:
    """The mesh files under ``folder`` (any depth, hidden files and folders skipped),
    sorted; links out of ``root`` (default: ``folder``'s parent, the dataset root of a
    category folder) are skipped (:func:`~beo_bench.objects.walk.walk_files`)."""
    base = Path(folder).absolute().parent.resolve() if root is None else Path(root).resolve()
    return walk_files(Path(folder), base, MESH_SUFFIXES)


class FolderLayout:
    """The per-category folder layout (:data:`FOLDER`)."""

    name = "folder"
    title = "folder"
    pattern = "<root>/<category>/**/<name>.{obj,off,ply,stl,glb,gltf}"
    root_env = "BEO_BENCH_FOLDER"
    default_units = "auto"
    axes_option = True
    key_form = "folder/<category>/<path of the mesh file>"

    def holds_models(self, folder: Path) -> bool:
        """A folder with a mesh file at any depth."""
        return any(mesh_files(folder))

    def category_name(self, dirname: str) -> str:
        return dirname

    def entries(self, root: Path, dirname: str) -> list[Entry]:
        out = []
        for f in mesh_files(root / dirname, root):
            ident = f.relative_to(root).as_posix()
            out.append(Entry(ident, dirname, hash_split(ident), f))
        return out

    def key_ok(self, parts: Sequence[str]) -> bool:
        return len(parts) >= 2

    def rotation(self, opts: LoadOptions) -> Mat3:
        return axes_rotation(opts.up, opts.front)

    def __repr__(self) -> str:
        return "FOLDER"


FOLDER = FolderLayout()
