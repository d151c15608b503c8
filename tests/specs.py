"""Registering a test's backend class (a :class:`~beo_bench.backend.Backend` subclass) as
a :class:`~beo_bench.backend.BackendSpec`: built without arguments, or with its options
dataclass when it has one."""

from __future__ import annotations

from typing import Any

from beo_bench import backend as B


def spec_of(cls: type[B.Backend], options: type = B.NoOptions, **caps: Any) -> B.BackendSpec:
    """The spec of ``cls`` under ``cls.name``: ``cls(options)`` when ``options`` is given,
    else ``cls()``; ``caps`` are its :class:`~beo_bench.backend.Capabilities`."""

    def build(opts: Any) -> B.Backend:
        return cls(opts) if options is not B.NoOptions else cls()  # type: ignore[call-arg]

    return B.BackendSpec(cls.name, build, options, B.Capabilities(**caps), module=cls.__module__)


def register_class(cls: type[B.Backend], options: type = B.NoOptions, **caps: Any) -> str:
    """Register :func:`spec_of` ``cls``; returns its name (``unregister_backend`` it)."""
    B.register(spec_of(cls, options, **caps))
    return cls.name
