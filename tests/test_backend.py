"""The backend interface: registry, entry-point plugins, the Estimate contract and the
conformance check on every registered backend."""

from __future__ import annotations

import sys
import textwrap
from dataclasses import replace

import numpy as np
import pytest

from beo_bench import backend as B
from beo_bench.errors import BackendError, EstimateError, ViewError
from beo_bench.objects import instance_from_key
from beo_bench.types import Estimate, View
from tests.plugins import install_plugin

# keep the class means small in tests (the default uses the whole train split); beo and
# hbeo load the published models (nothing trains in the tests, nor in a run)
FAST = {
    "random": {"mean_instances": 4},
    "icp": {"mean_instances": 4},
    "icp-plain": {"mean_instances": 4},
    "beo": {"so3_samples": 64},
    "swap": {"base": "random", "truth": "class+shape", "mean_instances": 4},
}


@pytest.fixture(scope="module")
def views() -> list[View]:
    return B.sample_views(3)


def test_in_tree_backends_are_listed() -> None:
    assert {"oracle", "random", "icp"} <= set(B.list_backends())
    # "every backend" (beo-bench all, make demo) leaves out tools that wrap another one
    assert "swap" in B.list_backends() and "swap" not in B.list_backends(diagnostic=False)


def test_the_in_tree_catalogue_names_each_class_under_its_own_name() -> None:
    # listings and reports read the catalogue without importing torch; each line's class
    # carries the same name, and the spec its line's role and description
    B._ensure_in_tree()
    for name, line in B.IN_TREE.items():
        spec = B.get_spec(name)
        assert (spec.cls.name, spec.role, spec.origin) == (name, line.role, "in-tree")
        assert B.describe_backend(name) == line.description
    assert B.in_tree("baseline") == ("icp-plain", "icp")
    assert B.in_tree("upper bound", "lower bound") == ("oracle", "random")


def test_a_catalogue_line_naming_a_class_of_another_name_is_refused(monkeypatch) -> None:
    monkeypatch.setitem(B.IN_TREE, "icp", B.IN_TREE["icp-plain"])
    monkeypatch.setattr(B, "_REGISTRY", {})
    with pytest.raises(BackendError, match="whose name is 'icp-plain'"):
        B._ensure_in_tree()


def test_a_plugins_role_is_its_classes_and_diagnostics_are_not_every_backend() -> None:
    class Tool(B.Backend):
        name = "test-tool"
        role = "diagnostic"

        def predict(self, view):
            raise NotImplementedError

    B.register(Tool)
    try:
        assert B.get_spec("test-tool").role == "diagnostic"
        assert "test-tool" in B.list_backends()
        assert "test-tool" not in B.list_backends(diagnostic=False)
    finally:
        B.unregister_backend("test-tool")
    Tool.role = "judge"  # type: ignore[assignment]
    with pytest.raises(BackendError, match="role 'judge'"):
        B.register(Tool)


@pytest.mark.parametrize("name", B.list_backends())
def test_every_registered_backend_conforms(name, views) -> None:
    B.check_backend(B.get_backend(name, **FAST.get(name, {})), views)


def test_unknown_backend_names_the_registered_ones() -> None:
    with pytest.raises(BackendError, match=r"registered: .*oracle"):
        B.get_backend("no-such-backend")


def test_duplicate_names_raise() -> None:
    with pytest.raises(BackendError, match="already registered"):
        B.register(type("Fake", (B.get_spec("random").cls,), {"name": "oracle"}))


def test_oracle_returns_the_truth(views) -> None:
    o = B.get_backend("oracle")
    for v in views:
        e = o.predict(v)
        gt = v.ground_truth
        assert e.class_index == gt.class_index
        np.testing.assert_array_equal(e.rotation, gt.R_cam)
        np.testing.assert_array_equal(e.translation, gt.t_cam)
        assert e.shape.shape == (32, 32, 32) and e.shape.max() == 1.0
    with pytest.raises(ViewError, match="ground_truth"):
        o.predict(replace(views[0], ground_truth=None))


def test_random_is_uniform_over_classes_and_deterministic_per_view(views) -> None:
    """The lower bound draws its class uniformly and its probabilities peak there (uniform
    probabilities made argmax answer class 0 on every view: 91 of 1000 on pose-3dof)."""
    r = B.get_backend("random", **FAST["random"])
    e = r.predict(views[0])
    C = len(views[0].categories)
    top = np.sort(e.class_probs)[::-1]
    assert top[0] == pytest.approx(2 / (C + 1)) and top[1] == pytest.approx(1 / (C + 1))
    assert e.class_probs.sum() == pytest.approx(1.0)
    np.testing.assert_array_equal(r.predict(views[0]).class_probs, e.class_probs)
    assert not np.array_equal(e.rotation, r.predict(views[1]).rotation)
    # its draws over many views are uniform over the classes (a chi-square test with C - 1
    # degrees of freedom at p = 0.001), and every class is drawn
    rng = np.random.default_rng(0)
    drawn = []
    for _ in range(200):
        depth = np.asarray(views[0].depth) * rng.uniform(0.9, 1.1)
        drawn.append(r.predict(replace(views[0], depth=depth)).class_index)
    counts = np.bincount(drawn, minlength=C)
    chi2 = ((counts - 200 / C) ** 2 / (200 / C)).sum()
    from scipy.stats import chi2 as chi2_dist

    assert chi2 < chi2_dist.ppf(0.999, C - 1) and counts.min() > 0, counts
    empty = replace(views[0], mask=np.zeros_like(views[0].mask))
    with pytest.raises(ViewError, match="no pixel"):
        r.predict(empty)


def _good(view: View) -> Estimate:
    C = len(view.categories)
    return Estimate(np.full(C, 1 / C), np.eye(3), np.zeros(3), np.ones(3), np.zeros((8, 8, 8)))


@pytest.mark.parametrize(
    "change, match",
    [
        ({"class_probs": np.ones(3)}, "class_probs"),
        ({"rotation": np.diag([1.0, 1.0, -1.0])}, "proper rotation"),
        ({"rotation": 2 * np.eye(3)}, "proper rotation"),
        ({"translation": np.array([0, np.nan, 0])}, "translation"),
        ({"size": np.array([0.1, 0.0, 0.1])}, "size"),
        ({"shape": np.full((8, 8, 8), 1.5)}, r"\[0, 1\]"),
        ({"shape": np.zeros((8, 8, 4))}, "D, D, D"),
    ],
)
def test_contract_violations_are_named(views, change, match) -> None:
    est = replace(_good(views[0]), **change)
    with pytest.raises(EstimateError, match=match):
        B.validate_estimate(est, views[0])


def test_a_nondeterministic_backend_fails_the_check(views) -> None:
    class Flaky(B.Backend):
        name = "flaky"

        def __init__(self, options=None) -> None:
            super().__init__(options)
            self.rng = np.random.default_rng()

        def predict(self, view: View) -> Estimate:
            e = _good(view)
            return replace(e, translation=self.rng.normal(size=3))

    with pytest.raises(EstimateError, match="not deterministic"):
        B.check_backend(Flaky(), views[:1])


def test_view_rejects_bad_shapes(views) -> None:
    v = views[0]
    with pytest.raises(ViewError, match="mask"):
        View(v.depth, v.mask[:-1], v.K, v.cam_to_world, v.categories)
    with pytest.raises(ViewError, match=r"\(H, W\)"):
        View(v.depth[None], v.mask, v.K, v.cam_to_world, v.categories)


def test_entry_point_plugin_is_listed_and_runs(tmp_path, views, monkeypatch) -> None:
    """A tiny third-party distribution, installed into a temporary path entry."""
    pkg = tmp_path / "beo_plugin_demo"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(
        textwrap.dedent(
            """
            import numpy as np
            from beo_bench.backend import Backend
            from beo_bench.types import Estimate

            class CentroidBackend(Backend):
                name = "centroid-demo"

                def predict(self, view):
                    C = len(view.categories)
                    return Estimate(np.full(C, 1 / C), np.eye(3), view.points().mean(axis=0),
                                    np.full(3, 0.1), np.full((16, 16, 16), 0.5, np.float32))
            """
        )
    )
    install_plugin(
        tmp_path,
        "beo-plugin-demo",
        {"centroid-demo": "beo_plugin_demo:CentroidBackend"},
        monkeypatch,
    )
    try:
        assert "centroid-demo" in B.load_plugins()
        assert "centroid-demo" in B.list_backends()
        b = B.get_backend("centroid-demo")
        B.check_backend(b, views)
        assert B.get_spec("centroid-demo").origin == "plugin beo-plugin-demo"
        # and it runs through the runner like an in-tree backend
        from beo_bench.bench.runner import RunConfig, run
        from beo_bench.bench.suites import get_suite

        suite = get_suite("pose-1dof").with_overrides(size=3)
        s = run(RunConfig(suite, "centroid-demo"), tmp_path / "run", progress=False)
        assert s["backend"] == "centroid-demo" and s["n"] == 3 and s["failures"] == 0
    finally:
        B.unregister_backend("centroid-demo")
        sys.modules.pop("beo_plugin_demo", None)


def test_swap_replaces_exactly_the_named_parts_and_hides_the_truth(views) -> None:
    seen = []

    class Spy(B.Backend):
        name = "spy"

        def predict(self, view):
            seen.append(view.ground_truth)
            return B.get_backend("random", mean_instances=4).predict(view)

    B.register(Spy)
    try:
        base = B.get_backend("spy").predict(views[0])
        seen.clear()  # from here on only swap calls the spy
        pose = B.get_backend("swap", base="spy", truth="pose").predict(views[0])
        gt = views[0].ground_truth
        np.testing.assert_array_equal(pose.rotation, gt.R_cam)
        np.testing.assert_array_equal(pose.translation, gt.t_cam)
        np.testing.assert_array_equal(pose.class_probs, base.class_probs)  # untouched
        np.testing.assert_array_equal(pose.shape, base.shape)
        every = B.get_backend("swap", base="spy", truth="class+pose+shape").predict(views[0])
        assert every.class_index == gt.class_index
        np.testing.assert_array_equal(every.shape, instance_from_key(gt.key).voxels(32))
        assert all(g is None for g in seen)  # the base never saw the truth
        with pytest.raises(ValueError, match="truth="):
            B.get_backend("swap", base="spy", truth="colour")
    finally:
        B.unregister_backend("spy")


def test_the_damaged_oracle_errs_by_exactly_the_amount_asked(views) -> None:
    """Issue 49's sensitivity rows: ``oracle`` with ``rot_deg`` turns the truth by exactly
    that angle (about an axis drawn per view, or the world's vertical), with ``trans_cm``
    moves it exactly that far, the same for the same view; ``shape=class-mean`` hands out
    the class's mean occupancy and size, and no mesh."""
    from scipy.spatial.transform import Rotation

    from beo_bench.errors import UsageError

    for axis in ("random", "up"):
        o = B.get_backend("oracle", rot_deg=30.0, rot_axis=axis, trans_cm=2.0)
        for v in views:
            e, gt = o.predict(v), v.ground_truth
            delta = Rotation.from_matrix(e.rotation @ np.asarray(gt.R_cam).T)
            assert np.degrees(delta.magnitude()) == pytest.approx(30.0, abs=1e-6)
            moved = np.linalg.norm(np.asarray(e.translation) - gt.t_cam)
            assert moved == pytest.approx(0.02, abs=1e-9)
            if axis == "up":  # a turn about the world's vertical: the axis is up
                up = np.asarray(v.cam_to_world)[:3, :3].T @ np.array([0.0, 0.0, 1.0])
                assert abs(delta.as_rotvec() @ up) == pytest.approx(np.radians(30.0), abs=1e-6)
            again = o.predict(v)
            np.testing.assert_array_equal(again.rotation, e.rotation)
    mean = B.get_backend("oracle", shape="class-mean", mean_instances=4)
    e = mean.predict(views[0])
    assert e.mesh is None and ((0 < e.shape) & (e.shape < 1)).any()  # an average of shapes
    np.testing.assert_array_equal(e.rotation, views[0].ground_truth.R_cam)
    with pytest.raises(UsageError, match="rot_deg"):
        B.get_backend("oracle", rot_deg=200.0)


def test_an_in_tree_backend_imports_only_its_own_module() -> None:
    """Getting ``oracle`` (what a run's driver and each worker do) imports its module
    alone, not the methods' modules, which import torch (seconds of every worker's start)."""
    import subprocess

    code = (
        "import sys; from beo_bench.backend import get_spec, list_backends; "
        "get_spec('oracle'); assert 'torch' not in sys.modules, 'torch imported'; "
        "assert 'beo_bench.perception.beo.backend' not in sys.modules; "
        "assert get_spec('hbeo').name == 'hbeo' and 'oracle' in list_backends()"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
