"""Shared fixtures for the planner tests: the shipped example scenarios."""

from __future__ import annotations

import json
from typing import Any

import pytest

from tests.paths import EXAMPLES

PAPER_CASES = [f"paper-{kind}{n}" for kind in ("circle", "random") for n in (2, 4, 6, 8)]


def load_example(name: str) -> dict[str, Any]:
    return json.loads((EXAMPLES / f"{name}.json").read_text())


@pytest.fixture
def paper4() -> dict[str, Any]:
    return load_example("paper-circle4")
