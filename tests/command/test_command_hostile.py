"""Issue 44's hostile requests and templates: what a web page, a mission file's utterances or
a strange request body can no longer do to the server (freeze it, steer it, make it 500)."""
from __future__ import annotations

import re
import threading
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hearth.executive.command.api import cross_site, host_is_served, parse_host
from hearth.executive.command.vocabulary import (MAX_TEMPLATE_TOKENS, compile_template,
                                          load_catalogue, read_templates)
from hearth.executive.errors import MissionError
from hearth.executive.missionfile import load_mission
from hearth.executive.testing import test_skills

WORST = "(x) " * 60 + "go"
#: 22 words that the 60 groups can share out in every way and that still fail at the end.
WORST_TEXT = "x " * 21 + "y"


def _mission_dir(tmp_path: Path, utterances: list[str], name: str = "worst") -> Path:
    d = tmp_path / name
    d.mkdir()
    items = "".join(f"  - {u!r}\n" for u in utterances)
    (d / f"{name}.yaml").write_text(
        f"hearth: 1\nname: {name}\nutterances:\n{items}"
        "parameters:\n  a: {type: string, default: x}\n  b: {type: string, default: y}\n"
        "tree:\n  skill: Act\n")
    return d


# -- utterance templates ---------------------------------------------------------------------

def test_sixty_optional_groups_do_not_freeze_matching(tmp_path):
    # The regular expression this template was compiled to backtracked through every way of
    # sharing 22 words among 60 groups (45 s and more); the table matcher fills 61 x 23 cells.
    d = _mission_dir(tmp_path, [WORST])
    entries, problems = load_catalogue([d], lambda f: load_mission(f, test_skills()))
    assert problems == []
    (t,) = entries["worst"].templates
    assert t.match(WORST_TEXT.strip()) is None
    assert t.match("x x x go") == {}


def test_a_template_of_too_many_tokens_is_refused_at_load_with_file_and_line(tmp_path):
    d = _mission_dir(tmp_path, ["(x) " * MAX_TEMPLATE_TOKENS + "go"])
    path = str(d / "worst.yaml")
    with pytest.raises(MissionError) as err:
        read_templates(load_mission(path, test_skills()), path)
    assert str(err.value).startswith(f"{path}:4: utterance ")
    assert f"more than {MAX_TEMPLATE_TOKENS} words, groups and slots" in str(err.value)


@pytest.fixture(scope="module")
def two_slot_mission(tmp_path_factory):
    d = _mission_dir(tmp_path_factory.mktemp("m"), ["go"])
    return load_mission(str(d / "worst.yaml"), test_skills())


_WORDS = st.sampled_from(["x", "y", "z"])
_TOKEN = st.one_of(
    _WORDS,
    st.lists(st.lists(_WORDS, min_size=1, max_size=2).map(" ".join), min_size=1, max_size=3)
    .map(lambda alts: "(" + "|".join(alts) + ")"),
    st.sampled_from(["{a}", "{b}"]))


@settings(max_examples=300, deadline=None, derandomize=True)
@given(tokens=st.lists(_TOKEN, min_size=1, max_size=6),
       text=st.lists(_WORDS, max_size=8).map(" ".join))
def test_the_table_matcher_answers_as_the_regular_expression_did(tokens, text,
                                                                 two_slot_mission):
    template = " ".join(tokens)
    try:
        t = compile_template(template, two_slot_mission, "m.yaml", 1)
    except MissionError:
        return          # two slots side by side, a slot twice: refused either way
    m = re.compile(t.source).match(f" {text} ")
    expected = None if m is None else {s.param: m.group(s.param).strip() for s in t.slots}
    assert t.match(text) == expected


def test_the_server_answers_health_while_the_worst_template_is_asked_for(tmp_path,
                                                                        make_server):
    srv = make_server(missions=[_mission_dir(tmp_path, [WORST])])
    answers = {}

    def ask():
        answers["command"] = srv.client.post("/api/commands", json={"text": WORST_TEXT})
    asker = threading.Thread(target=ask)
    asker.start()
    health = srv.client.get("/api/health")
    asker.join(60)
    assert health.status_code == 200 and health.json()["ok"] is True
    assert answers["command"].status_code == 200
    assert answers["command"].json()["outcome"] == "not_understood"
    # and the server still starts what it understands
    r = srv.client.post("/api/commands", json={"text": "x x go", "dry_run": True})
    assert (r.json()["outcome"], r.json()["mission"]) == ("run", "worst")


# -- cross-site requests ---------------------------------------------------------------------

def test_a_web_page_on_another_site_cannot_stop_or_cancel_runs(server):
    run = server.client.post("/api/runs", json={"mission": "wait_test"}).json()["run"]
    for path in ("/api/stop", f"/api/runs/{run['id']}/cancel"):
        for headers in ({"Origin": "http://evil.com"}, {"Origin": "null"},
                        {"Sec-Fetch-Site": "cross-site"}, {"Sec-Fetch-Site": "same-site"},
                        {"Origin": f"http://localhost:{server.thread.port + 1}"}):
            r = server.client.post(path, headers=headers)
            assert r.status_code == 403, (path, headers)
            message = r.json()["error"]["message"]
            assert message.startswith("a cross-site request may not change this server's state")
            assert "\n" not in message
    assert server.client.get(f"/api/runs/{run['id']}").json()["status"] in ("queued", "running")
    # A submit from another site is refused too, and starts nothing.
    r = server.client.post("/api/runs", json={"mission": "rest_test"},
                           headers={"Origin": "https://evil.com"})
    assert r.status_code == 403 and len(server.client.get("/api/runs").json()) == 1
    # The monitor page's own requests (same origin) and non-browser clients are served.
    origin = server.url.replace("127.0.0.1", "127.0.0.1")
    r = server.client.post("/api/stop", headers={"Origin": origin,
                                                 "Sec-Fetch-Site": "same-origin"})
    assert r.status_code == 200 and r.json()["cancelled"] == [run["id"]]


def test_reading_is_allowed_from_anywhere_and_origins_are_compared_whole():
    host = "127.0.0.1:8080"
    assert cross_site("GET", host, "http://evil.com", "cross-site") is None
    assert cross_site("POST", host, None, None) is None
    assert cross_site("POST", host, "http://127.0.0.1:8080", "same-origin") is None
    assert cross_site("POST", "localhost", "http://localhost:80", None) is None
    assert cross_site("POST", host, "http://127.0.0.1:8080.evil.com", None) is not None
    assert cross_site("PUT", host, "http://127.0.0.1", None) is not None
    assert cross_site("DELETE", host, None, "cross-site") is not None
    assert cross_site("POST", "robot.local:8080", "http://robot.local:9000", None,
                      ["robot.local"]) is None


# -- request bodies ---------------------------------------------------------------------------

@pytest.mark.parametrize("body, says", [
    (b'{"mission":"rest_test","priority":Infinity}', "Infinity is not a JSON number"),
    (b'{"mission":"rest_test","priority":NaN}', "NaN is not a JSON number"),
    (b'{"mission":"rest_test","priority":1e400}', "beyond a float's range"),
    (b'{"mission":"rest_test","priority":' + b"9" * 5000 + b"}", "an integer of 5000 digits"),
    (b'{"mission":"rest_test","params":{"presence":"\\ud800"}}', "lone surrogate"),
    (b'{"mission":"rest_test","mission":"wait_test"}', "the key 'mission' is given twice"),
])
def test_bodies_a_reply_could_not_hold_are_refused_with_422(server, body, says):
    r = server.client.post("/api/runs", content=body,
                           headers={"content-type": "application/json"})
    assert r.status_code == 422
    message = r.json()["error"]["message"]
    assert message.startswith("the request body is not strict JSON: ") and says in message
    assert server.client.get("/api/runs").json() == []


def test_a_parameter_value_with_a_lone_surrogate_is_refused(server):
    r = server.client.put("/api/parameters/presence", content=b'{"value":"\\udfff"}',
                          headers={"content-type": "application/json"})
    assert r.status_code == 422 and "lone surrogate" in r.json()["error"]["message"]


# -- Host --------------------------------------------------------------------------------------

def test_a_host_with_userinfo_or_a_bad_port_is_refused(server):
    port = server.thread.port
    for host in ("localhost:80@evil.com", f"localhost:{port}@evil.com", "user@localhost",
                 "localhost:99999", "localhost:", "localhost, evil.com", "local host",
                 f"localhost:{port}/x", f"127.0.0.1:{port + 1}"):
        r = server.client.get("/api/health", headers={"Host": host})
        assert r.status_code == 421, host
        assert "\n" not in r.json()["error"]["message"]
    assert server.client.get("/api/health", headers={"Host": f"localhost:{port}"}).status_code == 200


def test_host_headers_are_parsed_strictly():
    assert parse_host("LocalHost.:8080") == ("localhost", 8080)
    assert parse_host("[::1]:80") == ("::1", 80)
    assert parse_host("robot.local") == ("robot.local", None)
    for bad in ("localhost:80@evil.com", "a b", "x:0", "x:65536", "[::1", "", "x:y", "é.com"):
        assert parse_host(bad) is None, bad
    assert not host_is_served("localhost:80@evil.com", "127.0.0.1")
    assert not host_is_served("localhost:8081", "127.0.0.1", local_port=8080)
    assert host_is_served("localhost:8080", "127.0.0.1", local_port=8080)
    assert host_is_served("robot.local:443", "192.168.1.20", ["robot.local"], local_port=8080)
