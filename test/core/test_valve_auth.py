"""The per-session arming key: file permissions, signatures, replay and staleness, other sessions."""
import os
import stat

import pytest

from rollability_ros.core.rig import valve_auth


class FakeClock:
    def __init__(self, now_ns=10**12):
        self.now_ns = now_ns

    def __call__(self):
        return self.now_ns


def test_key_file_is_private_and_round_trips(tmp_path):
    path = str(tmp_path / "keys" / "valve.key")
    key = valve_auth.create_session_key(path)
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    assert stat.S_IMODE(os.stat(tmp_path / "keys").st_mode) == 0o700
    assert valve_auth.load_session_key(path) == key
    assert key.key.hex() not in repr(key), "the key never shows in logs or reprs"
    second = valve_auth.create_session_key(path)
    assert second.session != key.session and valve_auth.load_session_key(path) == second


def test_readable_by_others_or_malformed_is_refused(tmp_path):
    path = str(tmp_path / "valve.key")
    valve_auth.create_session_key(path)
    os.chmod(path, 0o640)
    with pytest.raises(valve_auth.AuthError, match="mode 0600"):
        valve_auth.load_session_key(path)
    os.chmod(path, 0o600)
    with open(path, "w", encoding="ascii") as stream:
        stream.write("not a key\n")
    with pytest.raises(valve_auth.AuthError, match="malformed"):
        valve_auth.load_session_key(path)
    with pytest.raises(valve_auth.AuthError, match="cannot read"):
        valve_auth.load_session_key(str(tmp_path / "missing.key"))
    link = tmp_path / "link.key"
    link.symlink_to(path)
    with pytest.raises(valve_auth.AuthError):
        valve_auth.load_session_key(str(link))


def test_signed_requests_verify_once_and_only_for_their_command(tmp_path):
    clock = FakeClock()
    key = valve_auth.create_session_key(str(tmp_path / "k"))
    signer, verifier = valve_auth.RequestSigner(key, clock), valve_auth.RequestVerifier(key, clock)
    arm = signer.sign("arm")
    assert verifier.verify(arm, "arm") == (True, "")
    assert verifier.verify(arm, "arm") == (False, "not authenticated: replayed request")
    fire = signer.sign("fire", 150)
    assert "wrong MAC" in verifier.verify(fire, "fire", 400)[1], "the pulse length is signed"
    assert "wrong MAC" in verifier.verify(fire, "arm")[1], "the command is signed"
    assert verifier.verify(fire, "fire", 150)[0]
    beats = [signer.sign("heartbeat") for _ in range(3)]
    assert len({b.counter for b in beats}) == 3, "counters strictly increase on one clock reading"
    assert all(verifier.verify(b, "heartbeat")[0] for b in reversed(beats)), "order does not matter, freshness does"
    assert verifier.rejected == 3


def test_stale_unsigned_and_other_session_requests_are_refused(tmp_path):
    clock = FakeClock()
    key = valve_auth.create_session_key(str(tmp_path / "k"))
    verifier = valve_auth.RequestVerifier(key, clock)
    old = valve_auth.RequestSigner(key, clock).sign("arm")
    clock.now_ns += valve_auth.FRESH_WINDOW_NS + 1
    assert "stale" in verifier.verify(old, "arm")[1]
    assert "no session key signature" in verifier.verify(valve_auth.Signature("", 0, ""), "arm")[1]
    other = valve_auth.create_session_key(str(tmp_path / "other"))
    foreign = valve_auth.RequestSigner(other, clock).sign("heartbeat")
    assert "signed for session" in verifier.verify(foreign, "heartbeat")[1]
    forged = valve_auth.Signature(key.session, clock(), foreign.mac)   # right session id, wrong key
    assert "wrong MAC" in verifier.verify(forged, "heartbeat")[1]


def test_default_path_separates_domains_and_namespaces(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    path = valve_auth.default_key_path("/rollability")
    assert path.startswith(str(tmp_path)) and "domain42" in path and "rollability" in os.path.basename(path)
    assert valve_auth.default_key_path("/") != path and valve_auth.default_key_path("/rollability", "7") != path


def test_remove_leaves_a_newer_sessions_key(tmp_path):
    path = str(tmp_path / "k")
    first = valve_auth.create_session_key(path)
    second = valve_auth.create_session_key(path)
    valve_auth.remove_session_key(path, first)
    assert valve_auth.load_session_key(path) == second
    valve_auth.remove_session_key(path, second)
    assert not os.path.exists(path)
