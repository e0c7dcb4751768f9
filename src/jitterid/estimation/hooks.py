"""The analysis functions a fit reaches at run time, registered by :mod:`jitterid.analysis`.

The layers of the package run one way (``docs/develop.md``, *Layering*): the analysis
functions read a :class:`~jitterid.estimation.result.FitResult`, so no module of
:mod:`jitterid.estimation` imports :mod:`jitterid.analysis`, not even inside a function. The
conveniences that start from a result (``result.step_response(t_s)``,
``result.physical_quantities()``, ``result.bode_band(f_hz)``, ...) and the post-fit check
that asks :func:`jitterid.detect_jitter` whether a collapsed jitter scale hides jitter reach
those functions through this registry instead: :mod:`jitterid.analysis` registers them when
it is imported. ``import jitterid`` imports no subpackage (so that ``jitterid --help`` stays
light): the package's ``__init__`` gives the registry a loader instead
(:func:`register_loader`), which imports :mod:`jitterid.analysis` at the first lookup that
finds nothing, in whatever process the fit runs (a Dask worker too).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["analysis", "register_analysis", "register_loader"]

_REGISTRY: dict[str, Callable[..., Any]] = {}
_LOADERS: list[Callable[[], object]] = []


def register_loader(load: Callable[[], object]) -> None:
    """Have ``load()`` fill the registry (import the package that registers) at the first
    lookup of a name not registered yet; each loader runs once.

    Parameters
    ----------
    load : callable
        Called with no argument.
    """
    if not callable(load):
        raise TypeError(f"load must be a callable; got {type(load).__name__}")
    _LOADERS.append(load)


def register_analysis(*functions: Callable[..., Any]) -> None:
    """Make ``functions`` reachable from the estimation layer by their ``__name__``.

    Parameters
    ----------
    *functions : callable
        Analysis functions (each taking a fit result or the data and a system first).
    """
    for fn in functions:
        if not callable(fn):
            raise TypeError(f"functions must be callables; got {type(fn).__name__}")
        _REGISTRY[fn.__name__] = fn


def analysis(name: str) -> Callable[..., Any]:
    """The analysis function registered as ``name``.

    Parameters
    ----------
    name : str
        Its ``__name__``, e.g. ``"step_response"``.

    Raises
    ------
    LookupError
        If no function of that name is registered (``jitterid.analysis`` not imported).

    Examples
    --------
    >>> import jitterid as ji
    >>> from jitterid.estimation.hooks import analysis
    >>> analysis("step_response") is ji.step_response
    True
    """
    while name not in _REGISTRY and _LOADERS:
        _LOADERS.pop(0)()
    try:
        return _REGISTRY[name]
    except KeyError:
        known = ", ".join(sorted(_REGISTRY)) or "none"
        raise LookupError(
            f"no analysis function {name!r} is registered (registered: {known}); import "
            "jitterid (its analysis package registers them when imported)"
        ) from None
