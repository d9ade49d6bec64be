"""``guidebelt certs``: the files every node needs, configs that load, a CA kept across runs."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from cli.app import app

pytest.importorskip("cryptography")


def test_certs_writes_every_node_and_keeps_the_ca(tmp_path):
    from daemon.service.config import load_config
    from protocol.certificates import common_name_of
    from protocol.settings import load_node_settings

    out = tmp_path / "tls"
    run = CliRunner().invoke(
        app, ["certs", "--out", str(out), "--user", "ann", "--installed-at", "/etc/guidebelt/tls"]
    )
    assert run.exit_code == 0, run.output
    stems = ["daemon", "user-ann", "belt-ann", "voice-ann", "rfid-ann", "mapper", "monitor"]
    for stem in stems:
        for ext in ("pem", "key", "toml", "json5"):
            assert (out / f"{stem}.{ext}").is_file(), f"{stem}.{ext}"
    assert common_name_of(out / "belt-ann.pem") == "belt:ann"
    # The daemon's table is a guidebelt.toml of its own; paths name where they will be read.
    cfg = load_config(out / "daemon.toml")
    assert cfg.zenoh.listen == ["tls/127.0.0.1:7447"] and cfg.zenoh.access.users == ["ann"]
    assert cfg.zenoh.tls.private_key == "/etc/guidebelt/tls/daemon.key"
    belt = load_node_settings(out / "belt-ann.toml")
    assert belt.connect == ["tls/127.0.0.1:7447"] and belt.access is None
    # A second run (a new user) keeps the CA, so the nodes certified before stay valid.
    ca = (out / "ca.pem").read_bytes()
    again = CliRunner().invoke(app, ["certs", "--out", str(out), "--user", "bob"])
    assert again.exit_code == 0, again.output
    assert (out / "ca.pem").read_bytes() == ca and (out / "belt-bob.pem").is_file()
    fresh = CliRunner().invoke(app, ["certs", "--out", str(out), "--new-ca"])
    assert fresh.exit_code == 0 and (out / "ca.pem").read_bytes() != ca


def test_the_daemons_certificate_names_loopback_for_its_workers_whatever_hosts_are_given(tmp_path):
    from cryptography import x509

    run = CliRunner().invoke(app, ["certs", "--out", str(tmp_path), "--host", "belt.example"])
    assert run.exit_code == 0, run.output
    cert = x509.load_pem_x509_certificate((tmp_path / "daemon.pem").read_bytes())
    names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert "belt.example" in names.get_values_for_type(x509.DNSName)
    assert [str(a) for a in names.get_values_for_type(x509.IPAddress)] == ["127.0.0.1"]


@pytest.mark.parametrize(
    "args, said",
    [
        (["--user", "Ann"], "bad user name 'Ann'"),
        (["--service", "daemon"], "unknown service 'daemon'"),
        (["--endpoint", "tcp/127.0.0.1:7447"], "every endpoint must be tls/"),
    ],
)
def test_certs_refuses_in_one_line(tmp_path, args, said):
    run = CliRunner().invoke(app, ["certs", "--out", str(tmp_path), *args])
    assert run.exit_code == 2
    assert said in run.output and len(run.output.strip().splitlines()) == 1, run.output
