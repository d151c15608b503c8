"""Per-class and per-file loading options (a dataset's ``beo-bench.toml``), the Y-up
warning, and how the dataset's warnings reach a user: the command line's words on the
command line, once, also from worker processes."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

from beo_bench.cli import main
from beo_bench.objects.datasets import (
    MANIFEST_NAME,
    ManifestError,
    SidewaysWarning,
    UnknownSizeWarning,
    check_dataset,
    open_dataset,
    vet,
)
from beo_bench.objects.prepare import prepare

Y_UP = trimesh.transformations.rotation_matrix(-np.pi / 2, [1.0, 0.0, 0.0])
"""Takes +z to +y: what a Y-up exporter writes for an upright object."""


def _cup(y_up: bool = False) -> trimesh.Trimesh:
    """A can-like cylinder 10 cm tall (metres), modelled +z up or +y up."""
    m = trimesh.creation.cylinder(radius=0.03, height=0.1, sections=48)
    if y_up:
        m.apply_transform(Y_UP)
    return m


def _mixed(root: Path) -> Path:
    """A folder that no command-wide flag loads right: a box in inches (read as cm by
    detection), rods whose files have no meaningful scale, and a Y-up cup."""
    for d in ("block", "rod", "cup"):
        (root / d).mkdir(parents=True)
    trimesh.creation.box(extents=(2.0, 1.5, 1.0)).export(root / "block" / "inch.stl")
    trimesh.creation.box(extents=(0.1, 0.05, 0.04)).export(root / "block" / "metre.stl")
    for i in range(2):
        trimesh.creation.cylinder(radius=0.1, height=1.0 + i).export(root / "rod" / f"r{i}.obj")
    _cup(y_up=True).export(root / "cup" / "y.obj")
    _cup().export(root / "cup" / "z.obj")
    return root


MANIFEST = """\
[classes.rod]          # every file of the class
size = 0.2

[files."rod/r1.obj"]   # one file: beats its class's entry
size = 0.1

[files."block/inch.stl"]
units = "in"

[files."cup/y.obj"]
up = "y"
"""


def test_manifest_sets_units_size_and_up_per_class_and_file(tmp_path: Path) -> None:
    root = _mixed(tmp_path / "data")
    plain = open_dataset(root)
    (root / MANIFEST_NAME).write_text(MANIFEST)
    dataset = open_dataset(root)
    objects = dataset.objects("all")
    got = {i.path.relative_to(root).as_posix(): i for i in objects}
    ext = {rel: np.sort(i.mesh.extents) for rel, i in got.items()}
    np.testing.assert_allclose(ext["block/inch.stl"], np.array([1.0, 1.5, 2.0]) * 0.0254)
    np.testing.assert_allclose(ext["block/metre.stl"], [0.04, 0.05, 0.1])  # untouched
    assert ext["rod/r0.obj"][-1] == pytest.approx(0.2)  # its class's size
    assert ext["rod/r1.obj"][-1] == pytest.approx(0.1)  # its own entry wins
    # the Y-up cup stands: its height is along z, as the z-up one's
    for name in ("cup/y.obj", "cup/z.obj"):
        np.testing.assert_allclose(got[name].mesh.extents, [0.06, 0.06, 0.1], atol=1e-3)
    # keys spell the options, so they resolve to the same objects without the manifest
    assert got["cup/y.obj"].key.endswith("?up=y") and "units=in" in got["block/inch.stl"].key
    for inst in got.values():
        assert plain.instance(inst.key).content_hash == inst.content_hash
    # the check builds each file with its own options
    files = {f.path: f for f in check_dataset(dataset).files}
    assert files["block/inch.stl"].units == "in" and files["rod/r0.obj"].units is None
    assert max(files["block/inch.stl"].extents or ()) == pytest.approx(0.0508)
    # the manifest is part of the dataset's identity: suites never mix the two
    assert dataset.short != plain.short and dataset.digest == plain.digest
    (root / MANIFEST_NAME).write_text(MANIFEST.replace("0.1\n", "0.12\n"))
    assert open_dataset(root).short not in (dataset.short, plain.short)


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("[classes.rods]\nsize = 0.2\n", "[classes.rods]: the dataset has no class 'rods'"),
        ('[files."rod/r9.obj"]\nsize = 0.2\n', "the dataset has no mesh file 'rod/r9.obj'"),
        ('[classes.rod]\nunits = "furlong"\n', "[classes.rod] units = 'furlong': use one of"),
        ("[classes.rod]\nsize = 3\n", "[classes.rod] size = 3: a tabletop object's largest"),
        ("[classes.rod]\nsize = true\n", "[classes.rod] size = True: give metres"),
        ('[classes.rod]\nup = "w"\n', "[classes.rod] up = 'w': axis 'w'"),
        ("[classes.rod]\ncolour = 1\n", "[classes.rod] colour: unknown key"),
        ("[rods]\nsize = 0.2\n", "unknown table [rods]"),
        ("[classes.rod\n", "not valid TOML"),
    ],
)
def test_a_bad_manifest_is_one_line_naming_the_file_and_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture, text: str, says: str
) -> None:
    root = _mixed(tmp_path / "data")
    (root / MANIFEST_NAME).write_text(text)
    with pytest.raises(ManifestError, match=r"beo-bench\.toml"):
        open_dataset(root)
    assert main(["objects", "--objects", str(root), "--split", "all"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"beo-bench: error: {root / MANIFEST_NAME}: ")
    assert says in err[0], err[0]


def test_a_y_up_file_is_named_with_the_flag_and_the_manifest_key(tmp_path: Path) -> None:
    root = _mixed(tmp_path / "data")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        vet(open_dataset(root))
    said = [str(w.message) for w in caught if issubclass(w.category, SidewaysWarning)]
    assert len(said) == 1, said  # the Y-up cup; not the z-up one, the boxes or the rods
    assert said[0].startswith(f"{root / 'cup' / 'y.obj'}: it looks modelled Y-up")
    assert "pass --up y for every file" in said[0]
    assert (
        f'up = "y" under [files."cup/y.obj"] or [classes.cup] in {root / MANIFEST_NAME}'
        in (said[0])
    )
    # loaded as the manifest says, it stands, and nothing is said
    (root / MANIFEST_NAME).write_text('[files."cup/y.obj"]\nup = "y"\n')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        vet(open_dataset(root))
    assert not [w for w in caught if issubclass(w.category, SidewaysWarning)]


def _normalised(root: Path, category: str) -> Path:
    (root / category).mkdir(parents=True)
    for i in range(3):
        trimesh.creation.box(extents=(1.0, 0.5 + 0.1 * i, 0.3)).export(root / category / f"{i}.stl")
    return root


def test_unknown_class_size_advice_is_the_cli_flag_on_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    root = _normalised(tmp_path / "data", "zorblax")
    argv = ["objects", "--objects", str(root), "--split", "all", "--units", "normalised"]
    assert main([*argv, "--workers", "2", "--resolution", "16"]) == 0
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if "has no known size" in ln]
    assert len(lines) == 1, err  # the check's, once; not again from the workers
    assert lines[0].startswith("beo-bench: warning: category 'zorblax' has no known size")
    assert (
        "set size = <metres> under [classes.zorblax] in the dataset's beo-bench.toml" in (lines[0])
    )
    assert "--size M" in lines[0] and "size={" not in lines[0]
    assert "warnings.warn" not in err  # no source line of a worker's default printout
    # the Python API's words: the loader's argument
    api = _normalised(tmp_path / "api", "quuxotl")
    with pytest.warns(UnknownSizeWarning) as said:
        _ = open_dataset(api, units="normalised").objects("all").get("quuxotl", 0).mesh
    assert "pass size={'quuxotl': <metres>} to open_dataset" in str(said[0].message)


def test_workers_warnings_reach_the_parent_once(tmp_path: Path) -> None:
    """Each worker warns once; the parent shows it once, as a warning of its own (not the
    worker's two-line printout with the source line)."""
    root = _normalised(tmp_path / "data", "wuggle")
    insts = list(open_dataset(root, units="normalised").objects("all"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        prepare(insts, D=16, workers=2, progress=False)
    sizes = [w for w in caught if issubclass(w.category, UnknownSizeWarning)]
    assert len(sizes) == 1 and "'wuggle' has no known size" in str(sizes[0].message)


def test_instances_read_the_mesh_the_check_built(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The dataset check builds every file once; instances (in the driver or in workers)
    then read that mesh from the cache instead of repairing the file again."""
    from beo_bench.objects import processing
    from beo_bench.objects.cache import mesh_hash

    root = _mixed(tmp_path / "data")
    dataset = open_dataset(root, repair="voxel")
    check_dataset(dataset)

    def no_repair(*args: object, **kw: object) -> None:
        raise AssertionError("the file was repaired again")

    monkeypatch.setattr(processing, "repair", no_repair)
    meshes = {i.key: i.mesh for i in dataset.objects("all")}
    monkeypatch.undo()
    monkeypatch.setenv("BEO_BENCH_CACHE", str(tmp_path / "another_cache"))  # built anew
    rebuilt = {i.key: i.mesh for i in open_dataset(root, repair="voxel").objects("all")}
    assert meshes.keys() == rebuilt.keys() and len(meshes) == 6
    for key, mesh in meshes.items():  # the cached mesh is the built one, to the bit
        assert mesh_hash(mesh) == mesh_hash(rebuilt[key])
