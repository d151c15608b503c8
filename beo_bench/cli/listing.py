"""What the registries hold, for ``beo-bench --help``: the suites, suite sets, backends
(installed plugins included) and cache kinds, one line each."""

from __future__ import annotations

import shutil

from beo_bench.backend import describe_backend, list_backends, load_plugins
from beo_bench.bench.suites import SUITE_SETS, SUITES
from beo_bench.objects.cache import KINDS


def _fit(name: str, text: str, name_width: int, width: int) -> str:
    """``  NAME  text`` on one line of at most ``width`` characters (cut at a word)."""
    text = " ".join(text.replace("`", "").split())
    line = f"  {name:<{name_width}}  {text}"
    if len(line) <= width:
        return line
    return line[: width - 3].rsplit(" ", 1)[0].rstrip(",;:") + "..."


def registry_listing(width: int | None = None) -> str:
    """The suites, backends (plugins included) and cache kinds, one line each with what it
    is, read from their registries; ``width``: the line length (default: the terminal's,
    as argparse's)."""
    width = width or max(60, shutil.get_terminal_size().columns - 2)
    sets = {
        n: f"{len(sizes)} suites at {min(sizes.values())}-{max(sizes.values())} items each"
        for n, sizes in sorted(SUITE_SETS.items())
    }
    load_plugins()  # a broken plugin is one warning, and is left out
    backends = {n: describe_backend(n) for n in list_backends()}
    sections = [
        ("suites (run --suite NAME)", {n: s.description for n, s in sorted(SUITES.items())}),
        ("suite sets (all --suites NAME)", sets),
        # plugins: packages' entry points in the group ENTRY_POINT_GROUP
        ("backends (run --backend NAME; installed plugins included)", backends),
        ("cache kinds (cache clear --kind KIND)", KINDS),
    ]
    out = []
    for head, entries in sections:
        w = max(map(len, entries))
        out += [f"{head}:", *(_fit(n, d, w, width) for n, d in entries.items()), ""]
    return "\n".join(out).rstrip()
