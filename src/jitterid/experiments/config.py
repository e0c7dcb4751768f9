"""Monte Carlo experiment definitions: TOML files validated into an :class:`Experiment`.

A definition names the true system and the model structure, the jitter law of every case,
the input, T, N, the noise, the estimators, the number of realizations and the seed. The
paper's three experiments ship as ``table1.toml``, ``table2.toml`` and ``table3.toml``
(:func:`packaged_path`); copy one and edit it for a study of your own. Every key is
checked when the file is loaded, and the library objects are built once, so a typo or a
bad value fails at once with an :class:`ExperimentError` naming the key, before any work.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..inputs import Input, Multisine, telegraph_input
from ..jitter import registry
from ..jitter.laws import JitterFamily, JitterLaw
from ..noise.models import NoiseModel, RationalNoise
from ..systems.structures import ModelStructure, PolePairGain, RationalModel
from ..systems.tf import TransferFunction
from ._schema import ExperimentError

__all__ = [
    "PAPER_EXPERIMENTS",
    "Case",
    "Experiment",
    "ExperimentError",
    "InputSpec",
    "LawSpec",
    "NoiseSpec",
    "SystemSpec",
    "packaged_path",
]

PAPER_EXPERIMENTS = ("table1", "table2", "table3")
# Packaged studies beyond the paper: "bj" is Table 2's system with coloured noise (issue 7).
EXTRA_EXPERIMENTS = ("bj",)
# Method prefixes of the Box-Jenkins estimators (fit(..., noise=...)): "bj-" with the jitter
# model of [jitter], "jbj-" with the family of each case's law kind estimated as well.
BJ_PREFIXES = ("bj-", "jbj-")
# law kind -> (class, parameter names); family kind -> (class, option names): the registry's
# tables spelled with "_" (jitterid.jitter.registry; a TOML file may spell kinds with "-" too)
LAWS: dict[str, tuple[Any, tuple[str, ...]]] = registry.table(registry.LAWS, "_")
FAMILIES: dict[str, tuple[Any, tuple[str, ...]]] = registry.table(registry.FAMILIES, "_")
Pairs = tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class LawSpec:
    """A jitter law by kind and parameters, e.g. ``sum_of_uniforms`` with n = 2, a = 0.5."""

    kind: str
    params: Pairs

    def build(self) -> JitterLaw:
        cls, _ = LAWS[self.kind]
        return cls(**dict(self.params))


@dataclass(frozen=True)
class Case:
    """One true jitter law of an experiment; ``paper_case`` is its block in the paper's table."""

    name: str
    law: LawSpec
    paper_case: int | None = None


@dataclass(frozen=True)
class InputSpec:
    """The known input of every realization, drawn anew for each (telegraph) or fixed."""

    kind: str
    margin: float
    levels: tuple[float, ...] = (-0.5, 0.5)
    mean_hold: float = 1.0
    freqs: tuple[float, ...] = ()
    amplitudes: tuple[float, ...] = ()
    phases: tuple[float, ...] | None = None
    steady_state: bool = False

    def build(self, duration: float, rng: np.random.Generator) -> Input:
        """The input on [0, duration) (a telegraph input draws from ``rng``)."""
        if self.kind == "telegraph":
            lo, hi = self.levels
            return telegraph_input(duration, rng, levels=(lo, hi), mean_hold=self.mean_hold)
        phases = None if self.phases is None else np.asarray(self.phases)
        return Multisine(
            np.asarray(self.freqs),
            np.asarray(self.amplitudes),
            duration,
            phases=phases,
            steady_state=self.steady_state,
        )


@dataclass(frozen=True)
class SystemSpec:
    """The true system and the model structure fitted to the data."""

    structure: str
    truth: Pairs = ()
    num: tuple[float, ...] = ()
    den: tuple[float, ...] = ()
    num_order: int = 0
    den_order: int = 0

    def model(self) -> ModelStructure | TransferFunction:
        """The structure passed to :func:`jitterid.fit` (a known TransferFunction for 'known')."""
        if self.structure == "known":
            return TransferFunction(np.asarray(self.num), np.asarray(self.den))
        if self.structure == "pole_pair":
            return PolePairGain()
        return RationalModel(self.num_order, self.den_order)

    def true_system(self) -> TransferFunction:
        model = self.model()
        if isinstance(model, TransferFunction):
            return model
        return model.system([v for _, v in self.truth])


@dataclass(frozen=True)
class NoiseSpec:
    """Coloured measurement noise v = (h * e)(t) of eq. (1c): a :class:`~jitterid.RationalNoise`
    structure and its true parameters (the data's v; the ``bj-``/``jbj-`` estimators fit it)."""

    num_order: int
    den_order: int
    truth: Pairs

    def structure(self) -> RationalNoise:
        return RationalNoise(self.num_order, self.den_order)

    def true_model(self) -> NoiseModel:
        return self.structure().model([v for _, v in self.truth])


def split_method(method: str) -> tuple[str, str]:
    """(prefix, criterion): ``"bj-gaussian"`` -> ``("bj-", "gaussian")``,
    ``"bcls"`` -> ``("", "bcls")``."""
    for prefix in BJ_PREFIXES:
        if method.startswith(prefix):
            return prefix, method[len(prefix) :]
    return "", method


@dataclass(frozen=True)
class Experiment:
    """A validated Monte Carlo experiment (see the module docstring and the packaged TOMLs)."""

    name: str
    title: str
    runs: int
    seed: int
    T: float
    N: int
    noise_std: float
    noise_known: bool
    input: InputSpec
    system: SystemSpec
    jitter_model: str
    jitter_options: Pairs
    cases: tuple[Case, ...]
    methods: tuple[str, ...]
    crb: bool = False
    crb_runs: int | None = None
    paper_table: int | None = None
    paper_labels: tuple[tuple[str, str], ...] = ()
    description: str = field(default="", compare=False)
    source: str = field(default="", compare=False)
    noise: NoiseSpec | None = None

    def estimation_jitter(self, case: Case, method: str = "") -> JitterLaw | JitterFamily:
        """What the estimators are told about the jitter: the true law, or the free family
        (for a ``jbj-`` method: the family of the case law's kind, default options)."""
        if split_method(method)[0] == "jbj-":
            return FAMILIES[case.law.kind][0]()
        if self.jitter_model == "known":
            return case.law.build()
        cls, _ = FAMILIES[self.jitter_model]
        return cls(**dict(self.jitter_options))

    def bound_runs(self) -> int:
        """How many realizations of each case store the Cramer-Rao bound: the first
        ``crb_runs`` (every one if None), at most ``runs``; 0 without ``crb``.

        The bound depends on the realization's input, so the report's CRB row averages the
        per-realization bounds (the diagonal of the inverse Fisher information of each input)
        over these realizations; it does not invert an averaged Fisher information.
        """
        if not self.crb:
            return 0
        return self.runs if self.crb_runs is None else min(self.runs, self.crb_runs)

    @property
    def duration(self) -> float:
        """Length of each realization's input: N T + ``input.margin``."""
        return self.N * self.T + self.input.margin

    def label(self, method: str) -> str:
        """The paper's name for ``method`` (``asml-diag`` -> AsML), else ``method`` itself."""
        return dict(self.paper_labels).get(method, method)

    def fingerprint(self) -> str:
        """Hash of everything that decides the numbers (not runs, titles or paper labels).

        Like ``runs``, ``crb_runs`` only says how many realizations are computed or read (the
        bound of realization r is the same whatever it is), so it is left out too."""
        core = dataclasses.replace(
            self,
            runs=0,
            crb_runs=None,
            title="",
            paper_table=None,
            paper_labels=(),
            description="",
            source="",
        )
        fields = dataclasses.asdict(core)
        if fields["noise"] is None:  # white-noise experiments keep their earlier fingerprint
            del fields["noise"]
        del fields["crb_runs"]
        text = json.dumps(fields, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def packaged_path(name: str) -> Path:
    """Path of a packaged experiment definition (``table1``-``table3``, ``bj``)."""
    names = (*PAPER_EXPERIMENTS, *EXTRA_EXPERIMENTS)
    if name not in names:
        raise ValueError(f"name must be one of {', '.join(names)}; got {name!r}")
    return Path(str(resources.files("jitterid.experiments") / "data" / f"{name}.toml"))
