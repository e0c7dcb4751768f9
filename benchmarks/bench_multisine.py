"""Steady-state multisine inputs: the closed forms against the generic routes, in one run.

The steady-state response to a multisine is a sum of tones. For the second-moment methods
(bcls, gaussian, ...) its jittered moments ``Response.jitter_moments`` are closed forms
((S1)-(S2) of ``jitterid.systems.tones``); the node route (quadrature over the jitter at
every sample, what the library did before) is the same code with that hook switched off.
For ``ml`` the closed forms are the response's parameter gradient, slope and second
derivatives (``Response.gradient``, ``slope``, ``second_derivatives``); the generic route
(forward differences of s in theta, a differenced slope, the Gauss-Newton matrix and a
differenced Hessian for the covariance, what the library did before) is the same code with
those hooks switched off. Both fit the same data; the script prints CPU seconds per fit,
their ratio and the machine's load before each row (ratios are stable on a shared machine,
absolute times are not).

    python benchmarks/bench_multisine.py --sizes 1000 10000 100000 --methods bcls ml
"""

from __future__ import annotations

import argparse
import contextlib
import os
import platform
import time
from collections.abc import Iterator

import numpy as np

import jitterid as ji
from jitterid.systems.model import Signal
from jitterid.systems.tf import Response


def _fit_cpu(data: ji.SampledData, method: str) -> tuple[float, str]:
    t0 = time.process_time()
    res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.3), method)
    return time.process_time() - t0, res.status.name


@contextlib.contextmanager
def _generic_route(method: str) -> Iterator[None]:
    """The closed forms switched off: the jittered moments (second-moment methods) or the
    parameter gradient, slope and second derivatives (ml)."""
    hooks = (
        {
            "has_gradient": property(lambda self: False),
            "has_slope": property(lambda self: False),
            "gradient": Signal.gradient,
            "slope": Signal.slope,
            "second_derivatives": Signal.second_derivatives,
        }
        if method == "ml"
        else {"jitter_moments": Signal.jitter_moments}
    )
    kept = {name: Response.__dict__[name] for name in hooks}
    try:
        for name, hook in hooks.items():
            setattr(Response, name, hook)
        yield
    finally:
        for name, hook in kept.items():
            setattr(Response, name, hook)


def _load() -> float:
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    ap.add_argument("--methods", nargs="+", default=["bcls", "gaussian"])
    ap.add_argument("--tones", type=int, default=1, help="number of input tones")
    args = ap.parse_args()
    load = _load()
    print(
        f"# jitterid multisine benchmark on {platform.node()} ({platform.machine()}, "
        f"{os.cpu_count()} cores, load {load:.1f}), {time.strftime('%Y-%m-%d')}"
    )
    freqs = np.linspace(0.17, 0.43, args.tones)
    print(
        f"# G = 2/(s+1), {args.tones} steady-state tone(s) at {np.round(freqs, 3).tolist()} Hz, "
        "U(-0.3, 0.3) known, T = 1, RationalModel(0, 1); CPU s per fit"
    )
    print(
        f"{'N':>8} {'method':<9} {'closed form':>12} {'generic':>11} {'ratio':>7} {'load':>5}  "
        "status"
    )
    u = ji.Multisine(freqs, np.ones(args.tones), end=1e12, steady_state=True)
    system = ji.TransferFunction([2.0], [1.0, 1.0])
    for n in args.sizes:
        rng = np.random.default_rng(n)
        data = ji.simulate(system, u, ji.Uniform(0.3), T=1.0, N=n, noise_std=0.01, rng=rng)
        for method in args.methods:
            load = _load()
            closed, status = _fit_cpu(data, method)
            with _generic_route(method):
                node, status_node = _fit_cpu(data, method)
            print(
                f"{n:>8} {method:<9} {closed:>11.3f}s {node:>10.3f}s {node / closed:>7.1f} "
                f"{load:>5.1f}  {status} / {status_node}",
                flush=True,
            )


if __name__ == "__main__":
    main()
