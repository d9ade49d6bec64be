"""With a certificate and key the page is served over TLS only (https and wss)."""

from __future__ import annotations

import json
import shutil
import ssl
import subprocess
import urllib.request
from pathlib import Path

import pytest


@pytest.mark.skipif(shutil.which("openssl") is None, reason="needs openssl to make a certificate")
@pytest.mark.timeout(60)
def test_served_over_tls_with_the_given_certificate(tmp_path: Path) -> None:
    from websockets.sync.client import connect

    from daemon.service.embedded import free_port
    from protocol.session import loopback, open_session
    from viewer.server import ServeSettings, ViewThread

    cert, key = tmp_path / "view.pem", tmp_path / "view.key"
    subprocess.run(
        ["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
         "-subj", "/CN=guidebelt-view", "-addext", "subjectAltName=IP:127.0.0.1",
         "-keyout", str(key), "-out", str(cert)],
        check=True, capture_output=True,
    )  # fmt: skip
    trust = ssl.create_default_context(cafile=str(cert))
    session = open_session(loopback())
    try:
        settings = ServeSettings(port=free_port(), certfile=cert, keyfile=key)
        with ViewThread(session, settings) as view:
            assert view.settings.url().startswith("https://127.0.0.1:")
            with urllib.request.urlopen(view.settings.url() + "state", context=trust) as r:
                assert json.load(r)["users"] == {}
            with connect(f"wss://127.0.0.1:{settings.port}/ws", ssl=trust) as ws:
                assert "users" in json.loads(ws.recv(timeout=5))
            with pytest.raises(OSError):  # plain http on the TLS port gets no page
                urllib.request.urlopen(f"http://127.0.0.1:{settings.port}/state", timeout=3)
    finally:
        session.close()
