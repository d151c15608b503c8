"""Typed backend options: a frozen dataclass per backend, parsed once from ``--opt KEY=VALUE``.

A backend declares its options as a frozen dataclass whose fields carry their default and
one line of documentation (:func:`option`); :func:`parse_options` turns the values a user
gave (JSON-parsed strings from the command line, or Python values) into that dataclass,
converting by each field's annotation, so no backend converts strings itself. An unknown key
or a value that is not of the field's type is a :class:`~beo_bench.errors.UsageError` that
lists every option with its type, default and documentation; so is a ``ValueError`` raised
by the dataclass's own ``__post_init__`` checks.
"""

from __future__ import annotations

import dataclasses
import numbers
import types
import typing
from collections.abc import Mapping
from typing import Any, Literal, TypeVar, Union

import numpy as np

from beo_bench.errors import UsageError

T = TypeVar("T")

_TRUE = ("1", "true", "yes", "on")
_FALSE = ("0", "false", "no", "off")


def option(default: Any, doc: str) -> Any:
    """A dataclass field with ``default`` and one line of documentation (shown by
    :func:`describe_options` and in every usage error about the options)."""
    if isinstance(default, (list, dict, set)):
        raise TypeError("an option's default must be immutable (use a tuple)")
    return dataclasses.field(default=default, metadata={"doc": doc})


def as_bool(x: object) -> bool:
    """A boolean option, also from its command-line spelling (``--opt mesh=no``). Anything
    else (``"maybe"``, ``2``, a list) raises :class:`UsageError` (a ValueError)."""
    if isinstance(x, str) and x.lower() in _TRUE + _FALSE:
        return x.lower() in _TRUE
    if isinstance(x, (bool, np.bool_)) or (isinstance(x, numbers.Integral) and x in (0, 1)):
        return bool(x)
    raise UsageError(
        f"expected a boolean, got {x!r}: use one of {', '.join(_TRUE)} (true) or "
        f"{', '.join(_FALSE)} (false)"
    )


class _Mismatch(Exception):
    """A value that is not of an option's type (the message says what it should be)."""


def _type_name(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin is Literal:
        return " or ".join(repr(a) for a in typing.get_args(tp))
    if origin in (Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(tp))
    if origin is tuple:
        args = typing.get_args(tp)
        inner = _PLURALS.get(args[0], "values") if args else "values"
        count = len(args) if args and args[-1] is not Ellipsis else "any number of"
        return f"a list of {count} {inner}"
    return {
        bool: "a boolean (true/false, yes/no, on/off, 1/0)",
        int: "an integer",
        float: "a number",
        str: "a string",
        type(None): "null",
    }.get(tp, getattr(tp, "__name__", str(tp)))


_PLURALS = {bool: "booleans", int: "integers", float: "numbers", str: "strings"}


def _coerce(value: Any, tp: Any) -> Any:
    """``value`` as an instance of annotation ``tp``, or :class:`_Mismatch`."""
    origin = typing.get_origin(tp)
    if tp is Any:
        return value
    if origin in (Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return None
        for a in args:
            if a is type(None):
                continue
            try:
                return _coerce(value, a)
            except _Mismatch:
                continue
        raise _Mismatch(_type_name(tp))
    if origin is Literal:
        if value in typing.get_args(tp):
            return value
        raise _Mismatch(_type_name(tp))
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise _Mismatch(_type_name(tp))
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_coerce(v, args[0]) for v in value)
        if len(value) != len(args):
            raise _Mismatch(_type_name(tp))
        return tuple(_coerce(v, a) for v, a in zip(value, args, strict=True))
    if tp is bool:
        try:
            return as_bool(value)
        except UsageError:
            raise _Mismatch(_type_name(tp)) from None
    real = isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
    if tp is int:
        if not real or float(value) != int(value):
            raise _Mismatch(_type_name(tp))
        return int(value)
    if tp is float:
        if not real:
            raise _Mismatch(_type_name(tp))
        return float(value)
    if tp is str:
        if isinstance(value, str):
            return value
        if real:  # ``--opt model=7`` parses as JSON 7: the name "7"
            return str(value)
        raise _Mismatch(_type_name(tp))
    if isinstance(tp, type) and isinstance(value, tp):
        return value
    raise _Mismatch(_type_name(tp))


def describe_options(cls: type) -> str:
    """``name (type, default D): doc`` for each option, ``; ``-separated ("it takes no
    options" for none)."""
    fields = [f for f in dataclasses.fields(cls) if not f.metadata.get("hidden")]
    if not fields:
        return "it takes no options"
    hints = typing.get_type_hints(cls)
    parts = [
        f"{f.name} ({_type_name(hints[f.name])}, default {f.default!r})"
        + (f": {f.metadata['doc']}" if f.metadata.get("doc") else "")
        for f in fields
    ]
    return "its options: " + "; ".join(parts)


def option_names(cls: type) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(cls))


def parse_options(cls: type[T], raw: Mapping[str, Any], who: str) -> T:
    """``raw`` (option name -> value) as an instance of the options dataclass ``cls`` of
    ``who`` (a backend's name, for messages); a :class:`UsageError` naming the option and
    listing the valid ones for an unknown key or a bad value."""
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"{cls!r} is not an options dataclass")
    if isinstance(raw, cls):
        return raw
    names = option_names(cls)
    unknown = sorted(set(raw) - set(names))
    if unknown:
        from beo_bench.names import did_you_mean

        # hidden options are real ones too, but a hint never points at one
        shown = [f.name for f in dataclasses.fields(cls) if not f.metadata.get("hidden")]
        hint = next((h for h in (did_you_mean(k, shown) for k in unknown) if h), "")
        raise UsageError(
            f"backend {who!r} has no option {', '.join(map(repr, unknown))}; "
            f"{hint}{describe_options(cls)} (on the command line: --opt KEY=VALUE)"
        )
    hints = typing.get_type_hints(cls)
    values: dict[str, Any] = {}
    for key, value in raw.items():
        try:
            values[key] = _coerce(value, hints[key])
        except _Mismatch as e:
            default = next(f.default for f in dataclasses.fields(cls) if f.name == key)
            raise UsageError(
                f"backend {who!r} option {key}={value!r}: expected {e} (default {default!r})"
            ) from None
    try:
        return cls(**values)
    except ValueError as e:  # the options' own checks (__post_init__)
        raise UsageError(f"backend {who!r}: {e} ({describe_options(cls)})") from e


def given(options: Any) -> dict[str, Any]:
    """The options that differ from their defaults (name -> value)."""
    return {
        f.name: getattr(options, f.name)
        for f in dataclasses.fields(options)
        if getattr(options, f.name) != f.default
    }
