"""Backend options and plugins fail with one ``beo_bench.errors`` line that says what to do:
unknown options list the backend's options, boolean spellings are checked, and a broken
third-party plugin is named and skipped while the others load."""

from __future__ import annotations

import sys
import textwrap
import warnings
from pathlib import Path

import pytest

from beo_bench import backend as B
from beo_bench.errors import BackendError, PluginError, UsageError
from beo_bench.options import as_bool
from tests.plugins import install_plugin


@pytest.mark.parametrize(
    "name, options, match",
    [
        (
            "icp",
            {"bogus": 1},
            r"no option 'bogus'.*starts \(an integer, default 24\).*trim \(a number, default 0.8\)",
        ),
        ("random", {"x": 1, "y": 2}, r"no option 'x', 'y'.*seed \(an integer, default 0\)"),
        ("icp", {"point_to_plane": "maybe"}, r"point_to_plane='maybe'.*boolean"),
        ("oracle", {"mesh": 2}, "boolean"),
        ("icp", {"starts": "abc"}, r"starts='abc': expected an integer \(default 24\)"),
        ("icp", {"starts": 2.5}, "integer"),  # int(2.5) would run 2 starts silently
        ("icp", {"trim": "most"}, r"trim='most': expected a number"),
        ("swap", {"truth": "nope"}, "truth='nope'"),  # the backend's own ValueError
        ("swap", {"base": "icp", "bogus": 1}, r"backend 'icp' has no option 'bogus'"),
        ("hbeo", {"bogus": 1}, r"no option 'bogus'.*samples \(an integer, default 25\)"),
    ],
)
def test_bad_backend_options_are_usage_errors(name, options, match) -> None:
    with pytest.raises(UsageError, match=match):
        B.get_backend(name, **options)


def test_good_option_spellings_are_accepted() -> None:
    b = B.get_backend("icp", starts=8.0, trim=1, point_to_plane="no")
    assert b.options.starts == 8 and b.options.point_to_plane is False
    assert B.backend_options("oracle") == {
        "resolution": 32, "mesh": True, "rot_deg": 0.0, "rot_axis": "random", "trans_cm": 0.0,
        "shape": "true", "seed": 0, "mean_instances": None,
    }  # fmt: skip


@pytest.mark.parametrize("value", ["maybe", "", 2, None, [True]])
def test_as_bool_refuses_what_is_not_a_boolean(value) -> None:
    with pytest.raises(UsageError, match=r"yes.*no"):
        as_bool(value)
    with pytest.raises(ValueError):  # still a ValueError for generic handlers
        as_bool(value)


@pytest.mark.parametrize(
    "value, expected",
    [("yes", True), ("OFF", False), ("1", True), (0, False), (True, True), (False, False)],
)
def test_as_bool_spellings(value, expected) -> None:
    assert as_bool(value) is expected


# -- plugins ------------------------------------------------------------------------------
GOOD = """
import numpy as np
from beo_bench.backend import Backend
from beo_bench.types import Estimate

class Good(Backend):
    name = "good-demo"

    def predict(self, view):
        C = len(view.categories)
        return Estimate(np.full(C, 1 / C), np.eye(3), np.zeros(3), np.full(3, 0.1),
                        np.full((8, 8, 8), 0.5, np.float32))

class Random(Good):
    name = "random"

INSTANCE = Good()

NOT_A_BACKEND = 42
"""

ENTRY_POINTS = {
    "broken-demo": "beo_plugin_broken_mod:Backend",
    "good-demo": "beo_plugin_good_mod:Good",
    "number-demo": "beo_plugin_good_mod:NOT_A_BACKEND",
    "instance-demo": "beo_plugin_good_mod:INSTANCE",
    "random": "beo_plugin_good_mod:Random",
}


@pytest.fixture
def plugins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """One installed distribution advertising a good backend and four bad ones: a module
    that fails to import, an object that is not a backend, a backend instance instead of
    its class, and a name that an in-tree backend already has."""
    (tmp_path / "beo_plugin_good_mod.py").write_text(textwrap.dedent(GOOD))
    (tmp_path / "beo_plugin_broken_mod.py").write_text("import no_such_dependency_xyz\n")
    install_plugin(tmp_path, "beo-plugin-mixed", ENTRY_POINTS, monkeypatch)
    monkeypatch.setattr(B, "_BROKEN", {})  # this process has warned about none of them yet
    B._ensure_in_tree()
    yield tmp_path
    B.unregister_backend("good-demo")
    for mod in ("beo_plugin_good_mod", "beo_plugin_broken_mod"):
        sys.modules.pop(mod, None)


def test_broken_plugins_are_named_skipped_and_the_others_load(plugins) -> None:
    random_before = B.get_spec("random")
    with pytest.warns(B.PluginWarning) as caught:
        names = B.load_plugins()
    assert names == ["good-demo"]  # the good one still loads
    assert B.get_spec("random") is random_before  # the clash did not replace the in-tree one
    messages = sorted(str(w.message) for w in caught)
    assert len(messages) == 4
    assert all("beo-plugin-mixed" in m and "fix, reinstall or uninstall" in m for m in messages)
    text = "\n".join(messages)
    assert "broken-demo = beo_plugin_broken_mod:Backend" in text
    assert "No module named 'no_such_dependency_xyz'" in text
    assert text.count("not a beo_bench.backend.Backend subclass") == 2  # number, instance
    assert "already registered" in text
    B.get_backend("good-demo")


def test_a_broken_plugin_warns_once_and_its_name_says_why(plugins) -> None:
    with pytest.warns(B.PluginWarning):
        B.load_plugins()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a second load (the runner's, a worker's) is quiet
        assert B.load_plugins() == ["good-demo"]
    with pytest.raises(PluginError, match=r"beo-plugin-mixed.*no_such_dependency_xyz") as e:
        B.get_backend("broken-demo")
    assert isinstance(e.value, BackendError) and e.value.exit_code == 1
    with pytest.raises(PluginError, match=r"not a beo_bench\.backend\.Backend subclass"):
        B.get_backend("number-demo")


def test_a_non_finite_option_value_is_a_usage_error() -> None:
    from beo_bench.bench.runs import parse_option_pairs

    assert parse_option_pairs(["starts=4", "scale_range=[0.5, 2]"]) == {
        "starts": 4,
        "scale_range": [0.5, 2],
    }
    for text in ("x=NaN", "x=Infinity", "x=-Infinity"):
        with pytest.raises(UsageError, match="give a finite number"):
            parse_option_pairs([text])


def test_a_list_option_names_its_type_in_plain_words() -> None:
    with pytest.raises(UsageError, match=r"expected a list of 2 numbers or null"):
        B.get_backend("icp", scale_range=3)


def test_swaps_base_options_are_not_an_option() -> None:
    with pytest.raises(UsageError, match="swap has no option 'base_options'"):
        B.get_backend("swap", base_options={"starts": 2})
    with pytest.raises(UsageError) as e:
        B.get_backend("swap", truth="nothing")
    assert "base_options" not in str(e.value)  # the listing shows only the user's options
