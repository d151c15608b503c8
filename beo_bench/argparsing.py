"""The command line's parser class: no abbreviations, and "did you mean" for a misspelt
flag or choice.

argparse takes any unambiguous prefix of a long option by default, so ``--episode 3`` was
silently read as ``--episodes 3``; a flag that later gains a sibling with the same prefix
would then change meaning under a user's script. :class:`SuggestingParser` turns that off
(``allow_abbrev=False``) for the top-level parser and every command's parser, and answers
an unknown flag or an invalid choice (a command, ``--track``, ``--split``, ...) with the
closest known one, compared case-insensitively (Python 3.11's argparse has no
``suggest_on_error``). Both stay argparse's own usage errors: one message, exit status 2.

Also the argument types that check a number's range (a usage error before anything runs),
and options declared by a config dataclass's fields (:func:`field_option`,
:func:`from_namespace`).
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

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


# -- argument types: an out-of-range number is a usage error (exit 2) before anything runs --
def bounded_int(lo: int, hi: int | None = None, why: str = "") -> Callable[[str], int]:
    """An argparse ``type`` accepting whole numbers in ``lo..hi`` (no upper bound when
    ``hi`` is None); ``why`` ends the message when a value is refused."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < lo or (hi is not None and value > hi):
            wanted = f">= {lo}" if hi is None else f"from {lo} to {hi}"
            wanted = f"a whole number {wanted}"
            raise argparse.ArgumentTypeError(f"{value} is out of range: give {wanted}{why}")
        return value

    parse.__name__ = "int"  # argparse names the type in some of its messages
    return parse


positive_int = bounded_int(1)
nonneg_int = bounded_int(0)
seed_int = bounded_int(0, why=" (numpy seeds are non-negative)")
# Voxel grids hold D^3 cells per instance (and training stacks thousands of them): 128^3
# is 2 M cells, 8 MB per float32 grid; beyond it memory, not the method, is the limit. Below
# 8 cells per edge a shape is no longer recognisable.
resolution_int = bounded_int(8, 128, why=" voxels per edge (memory grows as D^3)")


def positive_float(text: str) -> float:
    """An argparse ``type``: a finite number > 0 (``nan`` and ``inf`` refused)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"{text} is out of range: give a number > 0")
    return value


def fraction(text: str) -> float:
    """An argparse ``type``: a number in (0, 1]."""
    value = positive_float(text)
    if value > 1:
        raise argparse.ArgumentTypeError(f"{text} is out of range: give a number in (0, 1]")
    return value


def rate(text: str) -> float:
    """An argparse ``type``: a share in [0, 1] (``--max-failure-rate 0``: no failure)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError(f"{text} is out of range: give a share in [0, 1]")
    return value


def open_fraction(text: str) -> float:
    """An argparse ``type``: a number in (0, 1) (a significance level)."""
    value = positive_float(text)
    if value >= 1:
        raise argparse.ArgumentTypeError(f"{text} is out of range: give a number in (0, 1)")
    return value


# -- options from a config dataclass's fields -----------------------------------------------
# A command whose options configure a dataclass (``train``: TrainRequest) declares each
# option by its field: the flag, the destination and the default are the field's, so they
# cannot drift from the config; what is the command line's own (the type that checks the
# text, the help) is given where the option is declared. The namespace goes back into the
# dataclass by the same names (:func:`from_namespace`).
def field_option(container: Any, cls: type, name: str, **kwargs: Any) -> argparse.Action:
    """Add ``--NAME`` (underscores as dashes) for field ``name`` of dataclass ``cls`` to
    ``container`` (a parser or an argument group); its default is the field's unless
    ``default`` is given; the other keywords are ``add_argument``'s."""
    field = next((f for f in dataclasses.fields(cls) if f.name == name), None)
    if field is None:
        raise TypeError(f"{cls.__name__} has no field {name!r}")
    if "default" not in kwargs:
        if field.default is dataclasses.MISSING:
            raise TypeError(f"{cls.__name__}.{name} has no default: give one")
        kwargs["default"] = field.default
    flag = "--" + name.replace("_", "-")
    return container.add_argument(flag, dest=name, **kwargs)


T = TypeVar("T")


def from_namespace(cls: type[T], args: argparse.Namespace, **values: Any) -> T:
    """An instance of dataclass ``cls`` from ``args``: each field the command line has an
    option of takes its value, ``values`` (what the command computed, e.g. a dataset) win,
    and a field the command has no option of keeps its default."""
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    given = {k: v for k, v in vars(args).items() if k in names}
    return cls(**{**given, **values})
