"""The command line's parser class: no abbreviations, and "did you mean" for a misspelt
flag or choice.

argparse takes any unambiguous prefix of a long option by default, so ``--episode 3`` was
silently read as ``--episodes 3``; a flag that later gains a sibling with the same prefix
would then change meaning under a user's script. :class:`SuggestingParser` turns that off
(``allow_abbrev=False``) for the top-level parser and every command's parser, and answers
an unknown flag or an invalid choice (a command, ``--track``, ``--split``, ...) with the
closest known one, compared case-insensitively (Python 3.11's argparse has no
``suggest_on_error``). Both stay argparse's own usage errors: one message, exit status 2.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from beo_bench.names import closest, did_you_mean


class SuggestingParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` without abbreviations whose errors about an unknown flag or an
    invalid choice name the closest known one. Used as the top-level parser and as the
    ``parser_class`` of its commands, so every parser that parses arguments is one."""

    def __init__(self, *, allow_abbrev: bool = False, **kwargs: Any) -> None:
        # keywords only: argparse makes a command's parser with keywords (add_parser)
        super().__init__(allow_abbrev=allow_abbrev, **kwargs)

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        # argparse's own check, with a hint before the list (its wording is kept, so a
        # message still reads "invalid choice: 'x' (choose from ...)")
        choices = action.choices
        if choices is None or value in choices:
            return
        names = [str(c) for c in choices]
        hint = did_you_mean(str(value), names)
        listed = ", ".join(map(repr, names))
        raise argparse.ArgumentError(
            action, f"invalid choice: {value!r} ({hint}choose from {listed})"
        )

    def parse_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> argparse.Namespace:
        """As argparse's, but arguments nobody takes are refused by the command they were
        given to, naming the closest flag it has (``--episode``: did you mean
        ``--episodes``?)."""
        ns, extras = self.parse_known_args(args, namespace)
        if extras:
            parser = self._command_parser(ns)
            parser.error(unrecognized(extras, flags_of(parser) + flags_of(self)))
        return ns

    def _command_parser(self, ns: argparse.Namespace) -> argparse.ArgumentParser:
        """The parser of the command ``ns`` was parsed by (this one when it has none)."""
        for action in self._actions:
            choices = action.choices
            if isinstance(choices, dict):  # the sub-commands' action: name -> parser
                chosen = choices.get(getattr(ns, action.dest, None))
                if isinstance(chosen, argparse.ArgumentParser):
                    return chosen
        return self


def flags_of(parser: argparse.ArgumentParser) -> list[str]:
    """Every long option string ``parser`` takes (``--episodes``, ``--help``)."""
    return [s for a in parser._actions for s in a.option_strings if s.startswith("--")]


def unrecognized(extras: Sequence[str], flags: Sequence[str]) -> str:
    """argparse's "unrecognized arguments" message, with a hint for each unknown flag that
    is close to a real one."""
    hints = []
    for arg in extras:
        if arg.startswith("--"):
            flag = arg.split("=", 1)[0]
            match = closest(flag, flags)
            if match is not None and match != flag:
                hints.append(f"{flag}: did you mean {match}?")
    text = f"unrecognized arguments: {' '.join(extras)}"
    return text + (f" ({'; '.join(hints)})" if hints else "")
