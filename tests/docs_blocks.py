"""The code blocks of README.md and docs/*.md, and how ``tests/test_docs.py`` runs them.

The rules (docs/contributing.md, "Examples in the documentation", says the same to writers):

- A ```` ```python ```` block runs. The blocks of one page run in order in one fresh
  interpreter, in a temporary working directory, so a later block may use an earlier one's
  names and files.
- A ```` ```bash ```` (or ``sh``, ``console``) block runs in bash, in a temporary working
  directory shared by the page's shell blocks (in order), with ``beo-bench`` and ``make``
  as the only commands: ``beo-bench`` is the real command line with its sizes capped
  (:func:`capped`: 2 items a run, 1 worker, 2 instances a category), and ``make T`` checks
  that ``T`` is a Makefile target without running it. Another command fails the block.
- A shell block preceded by ``<!-- docs-test: check REASON -->`` does not run: each
  ``beo-bench`` command is parsed by the real parser (``beo_bench.cli.build_parser``) and
  its suites, backends and backend options are looked up (:func:`check_command`), so a
  wrong flag or name fails. Commands that cannot run in a test (:data:`CHECK_ONLY`: the
  demo, full campaigns, training, publishing, Ray, datasets the test does not have) must be
  in such a block: in a running block they fail, naming the marker to add.
- A ```` ```toml ```` block must parse (``tomllib``).
- A ```` ```yaml ```` block (a CI job) must parse (PyYAML), and every ``beo-bench`` command
  in its shell steps (the strings under ``run``, ``script``, ``before_script`` and
  ``after_script`` keys, :func:`yaml_commands`) is checked as in a ``check`` block.
- Any other block fails, unless it is preceded by ``<!-- docs-test: skip REASON -->``.

Run as a script (``python tests/docs_blocks.py ARGS``) it is the ``beo-bench`` of a running
shell block: it caps the sizes and calls ``beo_bench.cli.main``.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHELL_LANGS = ("bash", "sh", "console", "shell")
YAML_LANGS = ("yaml", "yml")
SCRIPT_KEYS = ("run", "script", "before_script", "after_script")
"""The keys whose strings are shell commands: a GitHub Actions step's ``run``, a GitLab CI
job's ``script`` and its neighbours."""
SHELL_OPERATORS = {"|", "||", "&", "&&", ";", ";;", ">", ">>", "<", "(", ")"}
MARKER = re.compile(r"<!--\s*docs-test:\s*(check|skip)\b\s*(.*?)\s*-->")

CHECK_ONLY = {
    "demo": "the whole demo (minutes)",
    "all": "a full campaign (every suite and backend)",
    "train": "training a model (minutes to hours)",
    "publish": "rewrites the published models",
    "render-dataset": "renders thousands of training crops",
}
"""Sub-commands that never run inside the docs test, with why."""

CHECK_ONLY_FLAGS = {
    "--ray": "needs a Ray cluster",
    "--objects": "needs a dataset the test does not have",
}


@dataclass(frozen=True)
class Block:
    """One fenced code block: its page, the line of its opening fence, its language, its
    text and the marker before it (``check`` / ``skip`` / None) with the marker's reason."""

    page: Path
    line: int
    lang: str
    code: str
    marker: str | None = None
    reason: str = ""

    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def pages() -> list[Path]:
    """README.md and every docs/*.md page (whatever pages exist)."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of ``page`` in order (``` and ~~~ fences; an unclosed fence is an
    error, since everything after it would silently stop being checked)."""
    lines = page.read_text().splitlines()
    out: list[Block] = []
    i = 0
    while i < len(lines):
        m = re.match(r"^(\s*)(`{3,}|~{3,})\s*([\w+-]*)", lines[i])
        if not m:
            i += 1
            continue
        indent, fence, lang = m.group(1), m.group(2), m.group(3).lower()
        start = i
        body: list[str] = []
        i += 1
        while i < len(lines) and not lines[i].strip().startswith(fence):
            line = lines[i]
            body.append(line[len(indent) :] if line.startswith(indent) else line.lstrip())
            i += 1
        if i == len(lines):
            raise AssertionError(f"{page.relative_to(ROOT)}:{start + 1}: unclosed code fence")
        i += 1
        marker, reason = None, ""
        prev = next((lines[j] for j in range(start - 1, -1, -1) if lines[j].strip()), "")
        mm = MARKER.search(prev)
        if mm:
            marker, reason = mm.group(1), mm.group(2)
        out.append(Block(page, start + 1, lang, "\n".join(body) + "\n", marker, reason))
    return out


def python_script(bs: list[Block]) -> str:
    """The python blocks of one page as one script; each block starts by recording where it
    is, so a traceback's line maps back to the page (see :func:`source_line`)."""
    parts = []
    for b in bs:
        parts.append(f"# --- {b.where()}\n{b.code}")
    return "\n".join(parts)


def source_line(bs: list[Block], script_line: int) -> str:
    """The page and line of line ``script_line`` (1-based) of :func:`python_script`."""
    n = 0
    for b in bs:
        header = n + 1
        body = b.code.count("\n")
        if header < script_line <= header + body:
            return f"{b.page.relative_to(ROOT)}:{b.line + script_line - header}"
        n = header + body + 1  # the blank line join adds
    return f"line {script_line} of the script"


def shell_commands(text: str) -> list[list[str]]:
    """The argv of every ``beo-bench`` command in the shell text ``text`` (a command ends
    at a line end, a shell operator or a comment; a backslash continues the line). The
    command word may be a path to the script (``.venv/bin/beo-bench``)."""
    import shlex

    out = []
    for line in text.replace("\\\n", " ").splitlines():
        lex = shlex.shlex(line, posix=True, punctuation_chars=True)
        lex.whitespace_split = True
        lex.commenters = "#"
        tokens = list(lex)
        for i, tok in enumerate(tokens):
            if tok.rsplit("/", 1)[-1] == "beo-bench" and (
                i == 0 or tokens[i - 1] in SHELL_OPERATORS
            ):
                argv = []
                for t in tokens[i + 1 :]:
                    if t in SHELL_OPERATORS:
                        break
                    argv.append(t)
                out.append(argv)
    return out


def yaml_commands(doc: object) -> list[list[str]]:
    """The ``beo-bench`` commands of a parsed YAML document: in the strings (or lists of
    strings) under :data:`SCRIPT_KEYS`, at any depth."""
    out: list[list[str]] = []
    if isinstance(doc, dict):
        for key, value in doc.items():
            if key in SCRIPT_KEYS:
                texts = value if isinstance(value, list) else [value]
                for text in texts:
                    if isinstance(text, str):
                        out += shell_commands(text)
            else:
                out += yaml_commands(value)
    elif isinstance(doc, list):
        for value in doc:
            out += yaml_commands(value)
    return out


def makefile_targets() -> set[str]:
    text = (ROOT / "Makefile").read_text()
    return {m.group(1) for m in re.finditer(r"^([A-Za-z][\w.-]*)\s*:(?!=)", text, re.M)}


def capped(argv: list[str]) -> list[str]:
    """``argv`` with the sizes a test can afford: 2 items a run and 1 worker for ``run`` and
    ``pick-check``, 2 items (and 2 training items) for ``export`` and ``score``, 2 instances
    a category for ``objects``. Raises ``ValueError`` for
    commands that must be in a ``check`` block."""
    if not argv:
        raise ValueError("beo-bench without a command")
    cmd = argv[0]
    if cmd in CHECK_ONLY:
        raise ValueError(
            f"`beo-bench {cmd}` cannot run in the docs test ({CHECK_ONLY[cmd]}): put it in a "
            "block marked <!-- docs-test: check REASON -->"
        )
    if cmd == "cache" and "clear" in argv:
        raise ValueError("`beo-bench cache clear` would clear the tests' cache: use a check block")
    for flag, why in CHECK_ONLY_FLAGS.items():
        if flag in argv:
            raise ValueError(f"`{flag}` {why}: put the command in a check block")

    def set_opt(args: list[str], flag: str, value: str) -> list[str]:
        if flag in args:
            i = args.index(flag)
            return [*args[: i + 1], value, *args[i + 2 :]]
        return [*args, flag, value]

    out = list(argv)
    if cmd in ("run", "pick-check"):
        out = set_opt(out, "--episodes", "2")
    if cmd in ("export", "score"):  # the same first items: a score reads the export's
        out = set_opt(out, "--episodes", "2")
    if cmd == "export":
        out = set_opt(out, "--train-items", "2")
    if cmd == "run":
        out = set_opt(out, "--workers", "1")
    if cmd == "objects":
        out = set_opt(out, "--per-category", "2")
    return out


def check_command(argv: list[str]) -> None:
    """Parse ``argv`` with the real parser and look up what it names (suites, tracks,
    backends and their options); raises ``AssertionError`` saying what is wrong."""
    from beo_bench.backend import get_backend, load_plugins
    from beo_bench.bench.runs import parse_backend_spec, parse_option_pairs
    from beo_bench.bench.suites import expand_suites, get_suite
    from beo_bench.cli import build_parser

    try:
        args = build_parser().parse_args(argv)
    except SystemExit as e:  # argparse prints why on stderr
        raise AssertionError(f"beo-bench {' '.join(argv)}: the parser refused it") from e
    load_plugins()
    suites = [args.suite] if getattr(args, "suite", None) else getattr(args, "suites", None)
    for s in expand_suites(suites or []):  # suite sets (smoke) are names too
        suite = get_suite(s)
        if getattr(args, "track", None):
            suite.with_overrides(track=args.track)
    backends: list[tuple[str, dict]] = []
    if getattr(args, "backend", None):
        backends.append((args.backend, parse_option_pairs(args.opt)))
    for spec in getattr(args, "backends", None) or []:
        backends.append(parse_backend_spec(spec))
    for name, kwargs in backends:
        get_backend(name, **kwargs)  # an unknown name or option raises UsageError


def main(argv: list[str]) -> int:
    from beo_bench.cli import main as cli_main

    try:
        args = capped(argv)
    except ValueError as e:
        print(f"docs test: {e}", file=sys.stderr)
        return 3
    return cli_main(args)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
