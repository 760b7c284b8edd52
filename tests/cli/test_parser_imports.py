"""Building `fleetplan`'s parser (every `--help`) loads no numpy: the flags' choices and
defaults come from plain modules (`gcs.fleet.choices`, `planner.model.choices`,
`gcs.sim.realism`), not from the parsers and the mock that use them."""

from __future__ import annotations

import json
import subprocess
import sys

_PROBE = ("import json, sys\n"
          "import gcs.cli.main as m\n"
          "m.build_parser()\n"
          "print(json.dumps({'numpy': 'numpy' in sys.modules, 'ours': sorted(\n"
          "    k for k in sys.modules if k.split('.')[0] in ('gcs', 'planner'))}))\n")


def test_building_the_parser_imports_no_numpy() -> None:
    """In a fresh interpreter, since this one has numpy loaded already."""
    done = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                          check=True)
    loaded = json.loads(done.stdout)
    assert loaded["numpy"] is False, f"numpy comes with one of {loaded['ours']}"
