"""The one table of jitter laws and families by name, for the command line and the TOML files.

A *law kind* names a :class:`~jitterid.JitterLaw` class and its parameters (the constructor's
keyword arguments); a *family kind* names a :class:`~jitterid.JitterFamily` class and its
options (bounds). Kinds are spelled with ``-`` on the command line (``sum-of-uniforms``) and
with ``_`` in TOML files (``sum_of_uniforms``); :func:`law_kind` and :func:`family_kind`
accept either, and :func:`table` gives the ``{name: (class, names)}`` mapping in one spelling.

Examples
--------
>>> from jitterid.jitter import registry
>>> registry.law_kind("generalized_normal").names
('std', 'beta')
>>> sorted(registry.table(registry.FAMILIES, "-"))
['dual-dirac', 'gaussian', 'generalized-normal', 'scale-mixture', 'sum-of-uniforms',
 'uniform']
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .laws import (
    Gaussian,
    GaussianFamily,
    NoJitter,
    SumOfUniforms,
    SumOfUniformsFamily,
    Uniform,
    UniformFamily,
)
from .regular import (
    DualDirac,
    DualDiracFamily,
    GaussianScaleMixture,
    GaussianScaleMixtureFamily,
    GeneralizedNormal,
    GeneralizedNormalFamily,
)

__all__ = ["FAMILIES", "LAWS", "UNITLESS", "Kind", "canonical", "family_kind", "law_kind", "table"]


@dataclass(frozen=True)
class Kind:
    """A law or family by name: its class and its parameter (law) or option (family) names."""

    name: str  # canonical spelling, with "-"
    cls: Any
    names: tuple[str, ...]


def canonical(kind: str) -> str:
    """The canonical spelling of a kind: lower case, ``-`` between words (``_`` accepted)."""
    return kind.strip().lower().replace("_", "-")


def _kinds(*kinds: Kind) -> dict[str, Kind]:
    return {k.name: k for k in kinds}


#: Law kinds (``none`` is the point mass; the command line spells it without a law).
LAWS: dict[str, Kind] = _kinds(
    Kind("uniform", Uniform, ("a",)),
    Kind("gaussian", Gaussian, ("sigma",)),
    Kind("sum-of-uniforms", SumOfUniforms, ("n", "a")),
    Kind("generalized-normal", GeneralizedNormal, ("std", "beta")),
    Kind("dual-dirac", DualDirac, ("rj", "dj")),
    Kind("scale-mixture", GaussianScaleMixture, ("sigma", "rho")),
    Kind("none", NoJitter, ()),
)

#: Family kinds and their options.
FAMILIES: dict[str, Kind] = _kinds(
    Kind("uniform", UniformFamily, ("a_max", "a_min")),
    Kind("gaussian", GaussianFamily, ("sigma_max", "sigma_min")),
    Kind("sum-of-uniforms", SumOfUniformsFamily, ("n_max", "a_max", "a_min")),
    Kind(
        "generalized-normal",
        GeneralizedNormalFamily,
        ("std_max", "std_min", "beta_min", "beta_max"),
    ),
    Kind("dual-dirac", DualDiracFamily, ("rj_max", "rj_min", "dj_max")),
    Kind("scale-mixture", GaussianScaleMixtureFamily, ("sigma_max", "sigma_min", "rho_max")),
)

#: Parameters and options without a time unit (all others are times).
UNITLESS = frozenset({"n", "n_max", "beta", "beta_min", "beta_max", "rho", "rho_max"})


def law_kind(kind: str) -> Kind | None:
    """The law kind of that name (either spelling), or None."""
    return LAWS.get(canonical(kind))


def family_kind(kind: str) -> Kind | None:
    """The family kind of that name (either spelling), or None."""
    return FAMILIES.get(canonical(kind))


def table(
    kinds: dict[str, Kind], sep: str, *, exclude: tuple[str, ...] = ()
) -> dict[str, tuple[Any, tuple[str, ...]]]:
    """``{name: (class, names)}`` with the names spelled with ``sep`` (``"-"`` or ``"_"``)."""
    return {k.replace("-", sep): (v.cls, v.names) for k, v in kinds.items() if k not in exclude}
