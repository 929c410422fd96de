"""What the monitor page loads from the API: a run's recent events, the state after a reload,
stop, mission names without paths, and Swagger UI served by the server itself."""
from __future__ import annotations

import re
from pathlib import Path

from hearth.executive.command.api import MAX_RECENT_EVENTS


def _stream(srv, run_id):
    """(id, kind, data) of every event of the run's stream, to its end."""
    out, seq, kind = [], None, None
    with srv.client.stream("GET", "/api/events", params={"run": run_id, "since": 0,
                                                         "close_on_end": True}) as r:
        for line in r.iter_lines():
            if line.startswith("id: "):
                seq = int(line[4:])
            elif line.startswith("event: "):
                kind = line[7:]
            elif line.startswith("data: ") and kind != "end":
                out.append((seq, kind, line[6:]))
    return out


def test_a_runs_recent_events_are_what_its_stream_sent(server):
    run_id = server.client.post("/api/runs", json={"mission": "fetch_test",
                                                   "params": {"object": "bowl"}}).json()["run"]["id"]
    streamed = [(seq, kind) for seq, kind, _ in _stream(server, run_id)]
    mine = [(seq, kind) for seq, kind in streamed if kind not in ("map", "vocabulary", "autonomy")]
    got = server.client.get(f"/api/runs/{run_id}/events").json()
    assert got["run"] == run_id and got["last_event"] >= mine[-1][0]
    assert [(e["id"], e["event"]) for e in got["events"]] == mine
    assert got["events"][0]["event"] == "submitted"
    assert got["events"][-1]["data"]["state"] == "succeeded"
    last3 = server.client.get(f"/api/runs/{run_id}/events", params={"limit": 3}).json()["events"]
    assert last3 == got["events"][-3:]
    assert server.client.get("/api/runs/nope/events").status_code == 404
    for bad in (0, MAX_RECENT_EVENTS + 1):
        assert server.client.get(f"/api/runs/{run_id}/events", params={"limit": bad}).status_code == 422


def test_state_after_a_reload_has_the_shown_runs_events_and_the_recent_runs(server):
    first = server.client.post("/api/runs", json={"mission": "fetch_test",
                                                  "params": {"object": "bowl"}}).json()["run"]["id"]
    _stream(server, first)
    held = server.client.post("/api/runs", json={"mission": "wait_test"}).json()["run"]["id"]
    list(_stream_until_running(server, held))
    st = server.client.get("/api/state").json()
    assert st["run"]["id"] == held and st["run"]["status"] == "running"
    assert [r["id"] for r in st["runs"]] == [held, first]
    kinds = [e["event"] for e in st["events"]]
    assert kinds[:2] == ["submitted", "run"] and "feedback" in kinds
    assert all(e["id"] <= st["last_event"] for e in st["events"])
    # What the page follows from last_event on: nothing before it comes twice.
    assert server.client.get("/api/state", params={"events": 0}).json()["events"] == []
    server.client.post(f"/api/runs/{held}/cancel")


def _stream_until_running(srv, run_id):
    with srv.client.stream("GET", "/api/events", params={"run": run_id, "since": 0}) as r:
        kind = None
        for line in r.iter_lines():
            if line.startswith("event: "):
                kind = line[7:]
            elif line.startswith("data: ") and kind == "status" and '"/wait_test/hold"' in line \
                    and '"RUNNING"' in line:
                yield kind, line
                return


def test_stop_cancels_the_queued_runs_then_the_running_one(server):
    ids = [server.client.post("/api/runs", json={"mission": "wait_test"}).json()["run"]["id"]
           for _ in range(3)]
    list(_stream_until_running(server, ids[0]))
    r = server.client.post("/api/stop", json={"reason": "everybody out"})
    assert r.status_code == 200
    # The queued ones first, so that none starts when the running one stops.
    assert r.json()["cancelled"] == [ids[1], ids[2], ids[0]]
    for run_id in ids:
        events = _stream(server, run_id)
        assert events[-1][1] == "run" and '"cancelled"' in events[-1][2]
        result = server.client.get(f"/api/runs/{run_id}").json()["result"]
        assert result["outcome"] == "cancelled" and result["reason"] == "everybody out"
    assert server.client.post("/api/stop").json() == {"cancelled": []}
    assert server.client.get("/api/health").json()["queued"] == []


def test_missions_are_named_by_file_name_never_by_path(server):
    missions = server.client.get("/api/missions").json()
    assert sorted(m["file"] for m in missions) == ["fetch.yaml", "oven.yaml", "rest.yaml",
                                                   "wait.yaml", "where.yaml"]
    assert str(Path(__file__).parent) not in server.client.get("/api/missions").text


def test_docs_page_loads_swagger_ui_from_this_server(server):
    page = server.client.get("/docs")
    assert page.status_code == 200
    assets = re.findall(r'(?:src|href)="([^"]+)"', page.text)
    assert assets and all(a.startswith("/static/swagger-ui/") for a in assets), assets
    assert "http" not in page.text.replace("http-equiv", "")
    for a in assets:
        r = server.client.get(a)
        assert r.status_code == 200 and len(r.content) > 500, a
    assert server.client.get("/static/swagger-ui/LICENSE").text.lstrip().startswith("Apache License")
    assert server.client.get("/redoc").status_code == 404    # no local copy of ReDoc
    for asset in ("/static/monitor.js", "/static/monitor.css"):
        assert server.client.get(asset).status_code == 200
