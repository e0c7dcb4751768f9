"""The one rule for what of an object is state and what is a cache.

A cache is

- the value of a :func:`functools.cached_property` (kept in the instance's ``__dict__``), or
- a dataclass field declared with :func:`cache_field` (a memo an object fills as it works,
  e.g. :class:`jitterid.TransferFunction`'s states over the last input, which grow with the
  record).

Everything else is state. Caches are not state: a class that memoises derives from
:class:`CachesAreNotState`, whose ``__getstate__`` leaves its caches out when the object is
pickled or copied (a cached property is made again when next read, a cache field starts
again at its default), so that a result pickles to the size of its state whatever was
evaluated on it (issue 25: a ``FitResult`` went from 9 kB to 2.2 MB after ``residuals()``).
``tests/estimation/test_caches_are_not_state.py`` checks that every class with a cache follows it.
"""

from __future__ import annotations

import dataclasses
from functools import cached_property
from typing import Any

__all__: list[str] = []

_CACHE = "jitterid_cache"


def cache_field(**kwargs: Any) -> Any:
    """A dataclass field that is a cache: not an argument, not shown, not compared, and left
    out of (reset to its default in) the pickled state.

    Parameters
    ----------
    **kwargs
        ``default`` or ``default_factory`` (default: ``default=None``), as for
        :func:`dataclasses.field`.
    """
    if "default" not in kwargs and "default_factory" not in kwargs:
        kwargs["default"] = None
    return dataclasses.field(
        init=False, repr=False, compare=False, metadata={_CACHE: True}, **kwargs
    )


def cache_names(cls: type) -> tuple[frozenset[str], tuple[dataclasses.Field[Any], ...]]:
    """The caches of ``cls``: the names of its cached properties, and its cache fields."""
    props = frozenset(
        name
        for klass in cls.__mro__
        for name, value in vars(klass).items()
        if isinstance(value, cached_property)
    )
    fields = (
        tuple(f for f in dataclasses.fields(cls) if f.metadata.get(_CACHE))
        if dataclasses.is_dataclass(cls)
        else ()
    )
    return props, fields


class CachesAreNotState:
    """Mixin: pickling or copying the object leaves its caches out (module doc)."""

    __slots__ = ()

    def __getstate__(self) -> dict[str, Any]:
        props, fields = cache_names(type(self))
        state = {k: v for k, v in self.__dict__.items() if k not in props}
        for f in fields:
            if f.default_factory is not dataclasses.MISSING:
                state[f.name] = f.default_factory()
            else:
                state[f.name] = f.default
        return state
