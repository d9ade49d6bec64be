"""The access rules are the topic table's, and the certificates are what zenoh needs."""

from __future__ import annotations

import stat

import pytest

from protocol import topics as T
from protocol.access import WORKER, Identity, access_control, identities_for, rules_for
from protocol.topics import Role

pytest.importorskip("cryptography")


def grants(who: Identity, flow: str, message: str) -> set[str]:
    return {
        key
        for rule in rules_for(who)
        if flow in rule["flows"] and message in rule["messages"]
        for key in rule["key_exprs"]
    }


def test_a_phone_puts_only_its_own_goals_and_settings_and_reads_only_its_own_keys():
    ann = Identity(Role.USER, "ann")
    assert grants(ann, "ingress", "put") == {"guidebelt/ann/goal", "guidebelt/ann/settings/set"}
    reads = grants(ann, "ingress", "declare_subscriber") | grants(ann, "ingress", "query")
    assert reads and all(k.startswith("guidebelt/ann/") or k == T.ALIVE.key() for k in reads)
    assert "guidebelt/ann/status" in reads
    assert grants(ann, "ingress", "declare_queryable") == set()


def test_only_the_mapper_and_sim_write_maps_and_answer_snapshot_queries():
    for who in identities_for(["ann"], [Role.MAPPER, Role.SIM, Role.MONITOR]):
        puts = grants(who, "ingress", "put")
        answers = grants(who, "ingress", "declare_queryable") | grants(who, "ingress", "reply")
        if who.role in (Role.MAPPER, Role.SIM):
            assert T.MAP_DELTA.any_user() in puts and T.MAP_SOURCE.any_user() in answers
        else:
            assert not any(k.endswith("/map/delta") for k in puts), who
            assert not any(k.endswith("/map/source") for k in answers), who


def test_nobody_but_the_daemon_publishes_what_the_daemon_publishes():
    daemon_only = [t for t in T.TOPICS if t.writers == {Role.DAEMON}]
    assert {T.BELT, T.VOICE, T.STATUS, T.PATH, T.SETTINGS} <= set(daemon_only)
    for who in identities_for(["ann", "bob"], [Role.MAPPER, Role.SIM, Role.MONITOR]):
        puts = grants(who, "ingress", "put") | grants(who, "ingress", "reply")
        for topic in daemon_only:
            assert not any(topic.matches(k.replace("*", "x")) for k in puts), (who, topic.name)


def test_a_belt_driver_hears_only_its_users_belt_and_sends_only_its_health_and_buttons():
    belt = Identity(Role.BELT, "bob")
    assert grants(belt, "ingress", "declare_subscriber") == {
        "guidebelt/bob/belt",
        "guidebelt/bob/settings",
    }
    assert grants(belt, "egress", "put") == {"guidebelt/bob/belt", "guidebelt/bob/settings"}
    assert grants(belt, "ingress", "put") == {
        "guidebelt/bob/belt/health",
        "guidebelt/bob/belt/button",
    }
    assert grants(belt, "ingress", "declare_liveliness_subscriber") == {T.ALIVE.key()}


def test_the_config_has_one_subject_and_policy_per_identity_and_denies_the_rest():
    config = access_control(identities_for(["ann"], [Role.MAPPER]))
    assert config["enabled"] is True and config["default_permission"] == "deny"
    names = [s["cert_common_names"] for s in config["subjects"]]
    assert names == [["belt:ann"], ["rfid:ann"], ["user:ann"], ["voice:ann"], ["mapper"]]
    ids = [r["id"] for r in config["rules"]]
    assert len(ids) == len(set(ids))
    assert all(r["permission"] == "allow" for r in config["rules"])
    assert {i for p in config["policies"] for i in p["rules"]} == set(ids)


def test_a_worker_does_the_daemons_part_for_every_user_on_loopback_and_nothing_daemon_wide():
    puts = grants(WORKER, "ingress", "put")
    assert {T.BELT.any_user(), T.STATUS.any_user(), T.VOICE.any_user()} <= puts
    assert T.GOAL.any_user() not in puts and T.MAP_DELTA.any_user() not in puts
    assert T.POSE.any_user() in grants(WORKER, "ingress", "declare_subscriber")
    assert grants(WORKER, "ingress", "query") == {T.MAP_SOURCE.any_user()}
    every = {k for rule in rules_for(WORKER) for k in rule["key_exprs"]}
    # Health and the liveliness token are the parent's: a worker can neither answer the one
    # (and so forge the daemon's health) nor hold the other. It holds its own token only.
    assert T.HEALTH.key() not in every and T.ALIVE.key() not in every
    assert grants(WORKER, "ingress", "liveliness_token") == {f"{T.WORKER_ALIVE.key()}/**"}
    others = identities_for(["ann"], [Role.MAPPER, Role.SIM, Role.MONITOR])
    assert all(grants(who, "ingress", "liveliness_token") == set() for who in others)
    config = access_control([*identities_for(["ann"], []), WORKER])
    (subject,) = [s for s in config["subjects"] if s["cert_common_names"] == ["daemon"]]
    assert subject["interfaces"] == ["lo"]
    assert all("interfaces" not in s for s in config["subjects"] if s is not subject)


def test_identities_name_their_user_exactly():
    assert Identity.parse("belt:ann") == Identity(Role.BELT, "ann")
    assert Identity.parse("mapper").common_name == "mapper"
    assert Identity(Role.VOICE, "ann").stem == "voice-ann"
    for bad in ("belt", "mapper:ann", "user:Ann", "root", "user:"):
        with pytest.raises(ValueError):
            Identity.parse(bad)


def test_certificates_are_signed_by_the_ca_and_keys_private(tmp_path):
    from cryptography import x509

    from protocol.certificates import common_name_of, issue, make_ca

    ca = make_ca(tmp_path)
    pair = issue(ca, "belt:ann", tmp_path, "belt-ann", hosts=("localhost", "10.0.0.2"))
    assert common_name_of(pair.certificate) == "belt:ann"
    cert = x509.load_pem_x509_certificate(pair.certificate.read_bytes())
    cert.verify_directly_issued_by(x509.load_pem_x509_certificate(ca.certificate.read_bytes()))
    san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert san.get_values_for_type(x509.DNSName) == ["localhost"]
    assert [str(a) for a in san.get_values_for_type(x509.IPAddress)] == ["10.0.0.2"]
    for key in (ca.private_key, pair.private_key):
        assert stat.S_IMODE(key.stat().st_mode) == 0o600


def test_a_tls_node_speaks_only_tls_with_its_certificate_and_no_shared_memory():
    import json

    from protocol.settings import TlsSettings, ZenohSettings

    tls = TlsSettings(root_ca="/t/ca.pem", certificate="/t/n.pem", private_key="/t/n.key")
    config = json.loads(ZenohSettings(connect=["tls/127.0.0.1:7447"], tls=tls).to_json5())
    link = config["transport"]["link"]
    assert link["protocols"] == ["tls"]
    assert link["tls"]["enable_mtls"] is True and link["tls"]["verify_name_on_connect"] is True
    assert link["tls"]["connect_private_key"] == "/t/n.key"
    assert config["transport"]["shared_memory"]["enabled"] is False
    assert config["scouting"]["multicast"]["enabled"] is False and "access_control" not in config
    for bad in (
        {"listen": ["tcp/127.0.0.1:7447"], "tls": tls},
        {"connect": ["tls/h:1"], "tls": tls, "multicast_scouting": True},
        {"connect": ["tcp/h:1"], "access": {"users": ["ann"]}},
    ):
        with pytest.raises(ValueError):
            ZenohSettings(**bad)


def test_every_row_of_the_table_names_who_may_send_and_receive():
    """A topic added without roles would be silently unreachable under the access rules."""
    for topic in T.TOPICS:
        if topic is T.WORKER_ALIVE:  # inside the daemon: its workers hold it, the parent watches
            assert topic.writers == {Role.DAEMON} and not topic.readers
            continue
        assert topic.writers and topic.readers, topic.name
        assert not (topic.writers & topic.readers), topic.name
