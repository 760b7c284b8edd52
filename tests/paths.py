"""Where things are in the source tree, for every test package."""

from __future__ import annotations

from pathlib import Path

__all__ = ["EXAMPLES", "ROOT"]

#: The repository's root.
ROOT = Path(__file__).resolve().parents[1]
#: The scenarios bundled with the planner (paper cases, scale cases).
EXAMPLES = ROOT / "planner" / "examples"
