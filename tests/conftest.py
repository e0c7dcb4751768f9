"""Fixtures shared by test modules in several folders of ``tests/`` (see tests/README.md)."""

from __future__ import annotations

import pytest

from jitterid.estimation.estimators import base as estimator_base


@pytest.fixture
def estimator_registry(monkeypatch):
    """A private copy of the estimator registry: estimators registered in a test vanish
    after it."""
    monkeypatch.setattr(estimator_base, "_REGISTRY", dict(estimator_base._REGISTRY))
