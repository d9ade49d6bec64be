"""``guidebelt record --demo``, ``replay --check`` and ``view``'s refusals, as a user runs them."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.mark.timeout(120)
def test_record_the_demo_then_check_it_against_a_fresh_daemon(daemon, tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from cli.app import app

    out = tmp_path / "walk.mcap"
    res = CliRunner().invoke(app, ["record", "--demo", "--pace", "0", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert " 0 dropped, 0 invalid" in " ".join(res.output.split())
    res = CliRunner().invoke(app, ["replay", str(out), "--check"])
    assert res.exit_code == 0, res.output
    assert "no difference" in res.output


def test_replay_refuses_a_file_that_is_not_a_recording(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from cli.app import app

    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file at all")
    res = CliRunner().invoke(app, ["replay", str(bad)])
    assert res.exit_code == 2 and "bad.mcap" in res.output


def test_view_refuses_a_certificate_without_its_key(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from cli.app import app

    res = CliRunner().invoke(app, ["view", "--cert", str(tmp_path / "c.pem")])
    assert res.exit_code != 0 and "both a certificate and its key" in " ".join(res.output.split())
