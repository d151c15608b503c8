"""Every example in README.md and docs/*.md runs, every relative link resolves, and no page
names a file outside the repository or an issue number.

How each kind of code block is run (or, for the few that cannot run in a test, checked) is
in ``tests/docs_blocks.py`` and, for writers, docs/contributing.md ("Examples in the
documentation"): python blocks run page by page in a fresh interpreter; shell blocks run
``beo-bench`` for real with small sizes, or, marked ``check``, through the real parser and
registries; any other block fails unless it is marked ``skip`` with a reason.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

import pytest
import yaml  # the dev extra's (pyproject.toml): a missing PyYAML fails, never skips

from tests.docs_blocks import (
    ROOT,
    SHELL_LANGS,
    YAML_LANGS,
    Block,
    blocks,
    check_command,
    makefile_targets,
    pages,
    python_script,
    source_line,
    yaml_commands,
)

PAGES = pages()
IDS = [str(p.relative_to(ROOT)) for p in PAGES]


def _env(tmp: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["MUJOCO_GL"] = env.get("MUJOCO_GL", "egl")
    # the session's cache (tests/conftest.py): the examples never touch the user's
    env["BEO_BENCH_CACHE"] = os.environ["BEO_BENCH_CACHE"]
    env["PYTHONPATH"] = str(ROOT)
    env.pop("PYTEST_CURRENT_TEST", None)
    # the examples' `beo-bench gate` would append to the CI job's own summary
    env.pop("GITHUB_STEP_SUMMARY", None)
    return env


def test_every_block_is_run_or_classified() -> None:
    """A block of a language the test does not run, or a marker that does not apply, fails
    here: nothing in the docs goes unchecked by accident."""
    bad = []
    for page in PAGES:
        for b in blocks(page):
            if b.lang == "python" and b.marker is not None:
                bad.append(f"{b.where()}: python blocks always run; drop the marker")
            elif b.lang in SHELL_LANGS and b.marker == "skip":
                bad.append(f"{b.where()}: shell blocks run or are checked, never skipped")
            elif b.marker is not None and not b.reason:
                bad.append(f"{b.where()}: the docs-test marker needs a reason")
            elif b.lang not in ("python", "toml", *SHELL_LANGS, *YAML_LANGS) and (
                b.marker != "skip"
            ):
                bad.append(
                    f"{b.where()}: a ```{b.lang or '(no language)'} block is neither run nor "
                    "checked: use python/bash/toml or mark it <!-- docs-test: skip REASON -->"
                )
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("page", PAGES, ids=IDS)
def test_python_blocks_run(page: Path, tmp_path: Path) -> None:
    bs = [b for b in blocks(page) if b.lang == "python"]
    if not bs:
        pytest.skip("no python block")
    script = tmp_path / "page_examples.py"
    script.write_text(python_script(bs))
    p = subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path,
        env=_env(tmp_path),
        capture_output=True,
        text=True,
        timeout=600,
    )
    if p.returncode != 0:
        lines = re.findall(rf'File "{re.escape(str(script))}", line (\d+)', p.stderr)
        where = source_line(bs, int(lines[-1])) if lines else "(no line in the traceback)"
        pytest.fail(f"example at {where} failed:\n{p.stderr[-4000:]}", pytrace=False)


PREAMBLE = """\
set -eo pipefail
PATH=/nonexistent-docs-test-path
where() {{ echo "{where_page}:$(( {first} + $1 - {offset} ))"; }}
make() {{
  for t in "$@"; do
    case " {targets} " in *" $t "*) ;;
      *) echo "docs test: make $t at $(where "${{BASH_LINENO[0]}}"): no such target" >&2
         return 3;;
    esac
  done
}}
beo-bench() {{
  {beo_bench} || {{
    echo "docs test: beo-bench $* at $(where "${{BASH_LINENO[0]}}") failed" >&2; return 3; }}
}}
trap 'echo "docs test: command failed at $(where "$LINENO")" >&2' ERR
"""

RUN_STUB = '"$DOCS_PY" "$DOCS_HELPER" "$@"'
CHECK_STUB = 'printf "%s\\0" "$#" "$@" >> "$DOCS_LOG"'  # recorded, checked after the block


def _shell_script(b: Block) -> str:
    head = PREAMBLE.format(
        targets=" ".join(sorted(makefile_targets())),
        beo_bench=CHECK_STUB if b.marker == "check" else RUN_STUB,
        where_page=b.page.relative_to(ROOT),
        first=b.line,
        offset=PREAMBLE.count("\n"),  # the block's line k is the script's line offset + k
    )
    return head + b.code


def _recorded(log: Path) -> list[list[str]]:
    """The argv of each ``beo-bench`` call a check block made (count, then the args)."""
    if not log.exists():
        return []
    fields = log.read_bytes().decode().split("\0")[:-1]
    out, i = [], 0
    while i < len(fields):
        n = int(fields[i])
        out.append(fields[i + 1 : i + 1 + n])
        i += 1 + n
    return out


@pytest.mark.parametrize("page", PAGES, ids=IDS)
def test_shell_blocks_run_or_parse(page: Path, tmp_path: Path) -> None:
    bs = [b for b in blocks(page) if b.lang in SHELL_LANGS]
    if not bs:
        pytest.skip("no shell block")
    work = tmp_path / "work"
    work.mkdir()
    env = _env(tmp_path)
    env["DOCS_PY"] = sys.executable
    env["DOCS_HELPER"] = str(ROOT / "tests" / "docs_blocks.py")
    for k, b in enumerate(bs):
        log = tmp_path / f"calls_{k}.log"
        env["DOCS_LOG"] = str(log)
        p = subprocess.run(
            ["bash", "-c", _shell_script(b)],
            cwd=work,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
        if p.returncode != 0:
            pytest.fail(f"shell block at {b.where()} failed:\n{p.stderr[-4000:]}", pytrace=False)
        calls = _recorded(log)
        if b.marker == "check":
            assert calls or "make" in b.code, f"{b.where()}: a check block without a command"
            _check_commands(calls, f"shell block at {b.where()}")


@pytest.mark.parametrize("page", PAGES, ids=IDS)
def test_toml_blocks_parse(page: Path) -> None:
    tomllib = pytest.importorskip("tomllib", reason="tomllib is in the standard library from 3.11")
    for b in blocks(page):
        if b.lang == "toml":
            tomllib.loads(b.code)


@pytest.mark.parametrize("page", PAGES, ids=IDS)
def test_yaml_blocks_parse_and_their_commands_check(page: Path) -> None:
    """A YAML block (a CI job) parses, and each ``beo-bench`` command of its shell steps
    goes through the real parser and registries, as a check block's do."""
    bs = [b for b in blocks(page) if b.lang in YAML_LANGS]
    if not bs:
        pytest.skip("no yaml block")
    for b in bs:
        try:
            doc = yaml.safe_load(b.code)
        except yaml.YAMLError as e:
            pytest.fail(f"yaml block at {b.where()} does not parse: {e}", pytrace=False)
        _check_commands(yaml_commands(doc), f"yaml block at {b.where()}")


def _check_commands(calls: Iterable[list[str]], where: str) -> None:
    """Each ``beo-bench`` argv goes through the real parser and registries."""
    for argv in calls:
        try:
            check_command(argv)
        except Exception as e:  # the parser's or a registry's refusal
            pytest.fail(f"{where}: `beo-bench {' '.join(argv)}`: {e}", pytrace=False)


def _prose(page: Path) -> list[tuple[int, str]]:
    """(line number, text) of the page's lines outside code blocks."""
    inside: set[int] = set()
    for b in blocks(page):
        inside.update(range(b.line, b.line + b.code.count("\n") + 2))
    return [
        (i, line)
        for i, line in enumerate(page.read_text().splitlines(), start=1)
        if i not in inside
    ]


LINK = re.compile(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


@pytest.mark.parametrize("page", PAGES, ids=IDS)
def test_relative_links_resolve(page: Path) -> None:
    missing = []
    for i, line in _prose(page):
        for target in LINK.findall(line):
            if re.match(r"^[a-z]+:", target) or target.startswith("#"):
                continue  # a web address or an anchor on the same page
            path = (page.parent / target.split("#", 1)[0]).resolve()
            if not path.is_relative_to(ROOT):
                missing.append(f"{page.name}:{i}: {target} points outside the repository")
            elif not path.exists():
                missing.append(f"{page.name}:{i}: {target} does not exist")
    assert not missing, "\n".join(missing)


OUTSIDE = re.compile(
    r"(?<![\w.~$])(?:/(?:home|work|tmp|Users|root|mnt|data|opt|srv|scratch)/|[A-Z]:\\)"
)
ISSUE = re.compile(r"\b(?:issues?|pr|pull request)\s*#?\d+", re.I)


@pytest.mark.parametrize("page", PAGES, ids=IDS)
def test_no_outside_paths_or_issue_numbers(page: Path) -> None:
    bad = []
    for i, line in enumerate(page.read_text().splitlines(), start=1):
        if OUTSIDE.search(line):
            bad.append(f"{page.name}:{i}: names a file outside the repository: {line.strip()}")
        if ISSUE.search(line):
            bad.append(f"{page.name}:{i}: an issue number (name the subject): {line.strip()}")
    assert not bad, "\n".join(bad)
