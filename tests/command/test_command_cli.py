"""`hearth serve`: localhost by default; any other address needs a token."""
from __future__ import annotations

from hearth.cli.main import main
from hearth.cli.commands.serve import check_bind


def test_serve_refuses_a_non_loopback_address_without_a_token(capsys, monkeypatch):
    monkeypatch.delenv("HEARTH_TOKEN", raising=False)
    assert main(["serve", "--host", "0.0.0.0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hearth serve: listening on 0.0.0.0 needs a token")
    assert len(err.splitlines()) == 1


def test_loopback_needs_no_token_and_other_addresses_do():
    assert check_bind("127.0.0.1", None) is None
    assert check_bind("::1", None) is None
    assert check_bind("localhost", None) is None
    assert check_bind("192.168.1.20", None) is not None
    assert check_bind("192.168.1.20", "s3cret") is None
