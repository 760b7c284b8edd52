"""`fleetplan keys new FILE`: a private key file, never printed, never overwritten."""

from __future__ import annotations

import stat
from pathlib import Path

from gcs.cli.main import main
from gcs.wire import load_key


def test_keys_new_writes_a_private_key_and_refuses_to_overwrite(tmp_path: Path,
                                                                capsys) -> None:
    path = tmp_path / "fleet.key"
    assert main(["keys", "new", str(path)]) == 0
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    key = load_key(path)
    out = capsys.readouterr().out
    assert str(path) in out and key.secret.hex() not in out
    assert main(["keys", "new", str(path)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert load_key(path) == key  # untouched
    assert main(["keys", "new", str(tmp_path / "missing" / "k.key")]) == 2
    assert "cannot create" in capsys.readouterr().err
