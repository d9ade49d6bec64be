"""How a command-line node meets the daemon: no multicast unless asked for, the daemon's
loopback endpoint when nothing is named, or the table `guidebelt certs` wrote."""

from __future__ import annotations

import inspect

import pytest
import typer

from cli.belt import belt
from cli.peer import DEFAULT_ENDPOINT, node_settings
from cli.rfid import rfid
from cli.voice import voice


def test_no_driver_scouts_by_default():
    assert inspect.signature(belt).parameters["multicast"].default is False
    for command in (voice, rfid):
        assert inspect.signature(command).parameters["scouting"].default is False


def test_nothing_named_means_the_daemons_loopback_endpoint():
    plain = node_settings(None)
    assert plain.connect == [DEFAULT_ENDPOINT] and not plain.multicast_scouting
    assert plain.loopback_only() and plain.tls is None
    assert node_settings(None, scout=True).connect == []
    assert node_settings(None, listen=["tcp/127.0.0.1:9000"]).connect == []


def test_a_nodes_table_with_the_endpoint_replaced(tmp_path):
    pytest.importorskip("cryptography")
    from protocol.deployment import certify
    from protocol.topics import Role

    nodes = {n.common_name: n for n in certify(tmp_path, ["ann"], [Role.MAPPER])}
    settings = node_settings(nodes["belt:ann"].toml, connect=["tls/10.0.0.2:7447"])
    assert settings.connect == ["tls/10.0.0.2:7447"] and settings.tls is not None
    with pytest.raises(typer.Exit):  # a plain endpoint with a TLS table: refused, one line
        node_settings(nodes["belt:ann"].toml, connect=["tcp/127.0.0.1:7447"])
