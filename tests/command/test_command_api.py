"""The HTTP API over a real socket: submit, follow events, cancel, bad input, concurrency,
approvals, parameters, map and vocabulary."""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

from hearth.worldmodel.pose import Pose


def _wait_end(srv, run_id):
    events = list(srv.events(run=run_id))
    assert events[-1][0] == "end"
    return events


def test_submit_mission_and_follow_its_events_to_success(server):
    r = server.client.post("/api/runs", json={"mission": "fetch_test",
                                              "params": {"object": "blue_cup"}})
    assert r.status_code == 201
    run = r.json()["run"]
    assert run["mission"] == "fetch_test" and run["params"] == {"object": "blue_cup"}
    events = _wait_end(server, run["id"])
    kinds = [k for k, _ in events]
    assert kinds[0] == "submitted"
    states = [d["state"] for k, d in events if k == "run"]
    assert states == ["running", "succeeded"]
    assert ("/fetch_test/find", "SUCCESS") in [(d["path"], d["status"]) for k, d in events
                                               if k == "status"]
    assert events[-1][1]["result"]["outcome"] == "succeeded"
    got = server.client.get(f"/api/runs/{run['id']}").json()
    assert got["status"] == "succeeded" and got["result"]["reason"] == "completed"
    tree = server.client.get(f"/api/runs/{run['id']}/tree").json()
    assert tree["root"]["status"] == "SUCCESS"
    assert [c["status"] for c in tree["root"]["children"]] == ["SUCCESS", "SUCCESS"]


def test_command_starts_the_mission_its_template_names(server):
    r = server.client.post("/api/commands", json={"text": "Bring me the blue cup, please!"})
    body = r.json()
    assert r.status_code == 200 and body["outcome"] == "run"
    assert body["mission"] == "fetch_test" and body["params"] == {"object": "blue_cup"}
    assert body["run"]["source"] == "command: Bring me the blue cup, please!"
    assert _wait_end(server, body["run"]["id"])[-1][1]["status"] == "succeeded"


def test_ambiguous_object_gets_a_clarifying_answer_and_starts_nothing(server):
    body = server.client.post("/api/commands", json={"text": "bring me the cup"}).json()
    assert body["outcome"] == "clarify" and body["run"] is None
    assert body["say"] == ("Which cup do you mean: the blue cup on the kitchen table or "
                           "the red cup on the kitchen table?")
    assert sorted(c["id"] for c in body["candidates"]) == ["blue_cup", "red_cup"]
    assert server.client.get("/api/runs").json() == []


def test_unknown_object_lists_what_is_known_instead_of_guessing(server):
    body = server.client.post("/api/commands", json={"text": "where is my green cup?"}).json()
    assert body["outcome"] == "clarify" and body["text_id"] == "T_UNKNOWN_OBJECT"
    assert body["say"].startswith("I do not know a green cup. Do you mean")
    assert {c["label"] for c in body["candidates"]} == {"blue cup", "red cup"}


def test_unrecognised_utterance_says_what_can_be_said(server):
    body = server.client.post("/api/commands", json={"text": "make me a coffee"}).json()
    assert body["outcome"] == "not_understood" and body["run"] is None
    # examples a person can say, not template syntax (issue 20)
    assert "bring me the " in body["say"] and "{" not in body["say"]


def test_cancel_mid_mission_ends_it_cancelled(server):
    run = server.client.post("/api/runs", json={"mission": "wait_test"}).json()["run"]
    cancelled = []
    seen = []
    for kind, data in server.events(run=run["id"]):
        seen.append((kind, data))
        if (kind == "status" and data["path"] == "/wait_test/hold"
                and data["status"] == "RUNNING" and not cancelled):
            r = server.client.post(f"/api/runs/{run['id']}/cancel", json={"reason": "user said stop"})
            assert r.status_code == 202
            cancelled.append(r.json())
    states = [d["state"] for k, d in seen if k == "run"]
    assert states == ["running", "halting", "cancelled"]
    assert seen[-1][1]["result"] == {"outcome": "cancelled", "reason": "user said stop",
                                     "outputs": {}, "ticks": seen[-1][1]["result"]["ticks"],
                                     "duration": seen[-1][1]["result"]["duration"],
                                     "robot_stopped": True}
    assert ("/wait_test/done", "RUNNING") not in [(d.get("path"), d.get("status")) for _, d in seen]
    again = server.client.post(f"/api/runs/{run['id']}/cancel")
    assert again.status_code == 409
    assert "already ended (cancelled)" in again.json()["error"]["message"]


def test_bad_input_gets_a_clear_4xx(server):
    c = server.client
    r = c.post("/api/runs", json={"mission": "make_coffee"})
    assert r.status_code == 404
    assert r.json()["error"]["message"].startswith("no mission named 'make_coffee' (known: fetch_test")
    r = c.post("/api/runs", json={"mission": "fetch_test", "params": {"object": 3}})
    assert r.status_code == 422
    assert r.json()["error"] == {"message": "parameter object: expected string, got 3",
                                 "param": "object",
                                 "problems": ["parameter object: expected string, got 3"]}
    r = c.post("/api/runs", json={"mission": "fetch_test"})
    assert r.status_code == 422 and r.json()["error"]["param"] == "object"
    r = c.post("/api/runs", content=b"{not json", headers={"content-type": "application/json"})
    assert r.status_code == 422 and r.json()["detail"][0]["type"] == "json_invalid"
    r = c.post("/api/commands", json={"text": ""})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "text"]
    r = c.post("/api/runs", json={"mission": "fetch_test", "params": {"object": "x"},
                                  "priority": 10**9})
    assert r.status_code == 422
    assert c.get("/api/runs/nope").status_code == 404
    assert c.get("/api/runs/nope").json() == {"error": {"message": "no run 'nope'"}}
    assert c.get("/api/events", params={"run": "nope"}).status_code == 404
    assert c.post("/api/approvals/a999", json={"approve": True}).status_code == 404
    assert server.client.get("/api/runs").json() == []


def test_token_is_required_when_set(make_server):
    srv = make_server(token="s3cret")
    assert srv.client.get("/api/health").status_code == 200
    import httpx
    bare = httpx.get(srv.url + "/api/health")
    assert bare.status_code == 401 and "token" in bare.json()["error"]["message"]
    # A token in a URL lands in access logs: ?token= is taken only by the event stream.
    assert httpx.get(srv.url + "/api/health", params={"token": "s3cret"}).status_code == 401
    assert httpx.get(srv.url + "/api/health", headers={"X-Hearth-Token": "wrong"}).status_code == 401
    assert httpx.get(srv.url + "/api/health", headers={"X-Hearth-Token": "s3cret"}).status_code == 200


def test_event_stream_takes_the_token_in_its_url_for_eventsource(make_server):
    import httpx
    srv = make_server(token="s3cret")
    run = srv.client.post("/api/runs", json={"mission": "fetch_test",
                                             "params": {"object": "blue_cup"}}).json()["run"]
    params = {"run": run["id"], "since": 0, "close_on_end": "true"}
    assert httpx.get(srv.url + "/api/events", params=params).status_code == 401
    with httpx.stream("GET", srv.url + "/api/events", params={**params, "token": "s3cret"},
                      timeout=30.0) as r:
        assert r.status_code == 200
        assert r.headers["content-type"].startswith("text/event-stream")
        kinds = [line[7:] for line in r.iter_lines() if line.startswith("event: ")]
    assert kinds[0] == "submitted" and kinds[-1] == "end"


def test_idempotency_key_returns_the_same_run_and_never_runs_twice(server):
    body = {"mission": "fetch_test", "params": {"object": "bowl"}, "idempotency_key": "k-1"}
    first = server.client.post("/api/runs", json=body)
    again = server.client.post("/api/runs", json=body)
    assert first.status_code == 201 and again.status_code == 200
    assert again.json()["created"] is False
    assert first.json()["run"]["id"] == again.json()["run"]["id"]
    other = server.client.post("/api/runs", json={**body, "params": {"object": "sugar"}})
    assert other.status_code == 409
    assert len(server.client.get("/api/runs").json()) == 1
    # The same through the header, for commands.
    h = {"Idempotency-Key": "say-1"}
    a = server.client.post("/api/commands", json={"text": "bring me the bowl"}, headers=h).json()
    b = server.client.post("/api/commands", json={"text": "bring me the bowl"}, headers=h).json()
    assert a["run"]["id"] == b["run"]["id"] and b["created"] is False


def test_many_clients_at_once_each_command_runs_exactly_once(server):
    started: dict[str, int] = {}
    lock = threading.Lock()

    def count(ev):
        if ev.kind == "run" and ev.data.get("state") == "running":
            with lock:
                started[ev.run] = started.get(ev.run, 0) + 1
    server.service.executive.subscribe(count)

    def submit(i):
        import httpx
        with httpx.Client(base_url=server.url, timeout=30) as c:
            # every client retries once, as a flaky network would make it
            body = {"mission": "fetch_test", "params": {"object": "bowl"},
                    "idempotency_key": f"client-{i}"}
            a = c.post("/api/runs", json=body).json()["run"]["id"]
            b = c.post("/api/runs", json=body).json()["run"]["id"]
            assert a == b
            return a

    with ThreadPoolExecutor(16) as pool:
        ids = list(pool.map(submit, range(24)))
    assert len(set(ids)) == 24
    for rid in ids:
        _wait_end(server, rid)
    runs = {r["id"]: r for r in server.client.get("/api/runs", params={"limit": 100}).json()}
    assert {runs[i]["status"] for i in ids} == {"succeeded"}
    assert started == {i: 1 for i in ids}


def test_higher_priority_preempts_the_running_mission(server):
    low = server.client.post("/api/runs", json={"mission": "wait_test"}).json()["run"]
    for kind, data in server.events(run=low["id"], close_on_end=False,
                                    until=lambda k, d: k == "run" and d["state"] == "running"):
        pass
    high = server.client.post("/api/runs", json={"mission": "fetch_test", "priority": 5,
                                                 "params": {"object": "bowl"}}).json()["run"]
    assert _wait_end(server, low["id"])[-1][1]["result"]["outcome"] == "preempted"
    assert _wait_end(server, high["id"])[-1][1]["status"] == "succeeded"


def test_runtime_parameter_is_checked_and_set(server):
    c = server.client
    assert c.get("/api/parameters").json()["presence"]["value"] == "home"
    r = c.put("/api/parameters/presence", json={"value": "away"})
    assert r.status_code == 200 and c.get("/api/parameters").json()["presence"]["value"] == "away"
    r = c.put("/api/parameters/presence", json={"value": "mars"})
    assert r.status_code == 422
    assert r.json()["error"]["message"] == "parameter presence: expected one of ['home', 'away'], got 'mars'"
    r = c.put("/api/parameters/volume", json={"value": 3})
    assert r.status_code == 404 and "presence" in r.json()["error"]["message"]


def test_skill_above_the_granted_level_waits_for_approval(make_server):
    srv = make_server(granted=1)
    body = srv.client.post("/api/commands", json={"text": "turn off the oven"}).json()
    run_id = body["run"]["id"]
    decided = []
    events = []
    for kind, data in srv.events(run=run_id):
        events.append((kind, data))
        if kind == "approval" and data["state"] == "pending" and not decided:
            pending = srv.client.get("/api/approvals", params={"pending": True}).json()
            assert [(p["skill"], p["level"], p["granted"], p["path"]) for p in pending] == [
                ("TurnTestKnob", 2, 1, "/oven_test/turn")]
            # Other work goes on while it waits: a second client gets its mission queued.
            assert srv.client.post("/api/runs", json={"mission": "where_test",
                                                      "params": {"object": "bowl"}}).status_code == 201
            r = srv.client.post(f"/api/approvals/{data['id']}", json={"approve": True, "by": "tester"})
            assert r.status_code == 200 and r.json()["state"] == "approved"
            decided.append(data["id"])
    assert events[-1][1]["status"] == "succeeded"
    feedback = [d["message"] for k, d in events if k == "feedback" and d["path"] == "/oven_test/turn"]
    assert feedback[0].startswith("waiting for approval: TurnTestKnob acts with autonomy 2")
    again = srv.client.post(f"/api/approvals/{decided[0]}", json={"approve": False})
    assert again.status_code == 409


def test_refused_approval_fails_the_step_with_the_reason(make_server):
    srv = make_server(granted=0)
    run_id = srv.client.post("/api/runs", json={"mission": "oven_test"}).json()["run"]["id"]
    for kind, data in srv.events(run=run_id):
        if kind == "approval" and data["state"] == "pending":
            srv.client.post(f"/api/approvals/{data['id']}",
                            json={"approve": False, "reason": "the user is cooking"})
    result = srv.client.get(f"/api/runs/{run_id}").json()["result"]
    assert result["outcome"] == "failed"
    assert result["reason"] == ("/oven_test/turn failed: TurnTestKnob not started: the operator "
                                "refused (the user is cooking)")


def test_raising_the_granted_level_approves_what_waits(make_server):
    srv = make_server(granted=1)
    run_id = srv.client.post("/api/runs", json={"mission": "oven_test"}).json()["run"]["id"]
    for kind, data in srv.events(run=run_id):
        if kind == "approval" and data["state"] == "pending":
            assert srv.client.put("/api/autonomy", json={"level": 2}).json()["granted"] == 2
    assert srv.client.get(f"/api/runs/{run_id}").json()["status"] == "succeeded"
    assert srv.client.put("/api/autonomy", json={"level": 7}).status_code == 422


def test_cancel_while_waiting_for_approval_withdraws_the_request(make_server):
    srv = make_server(granted=1)
    run_id = srv.client.post("/api/runs", json={"mission": "oven_test"}).json()["run"]["id"]
    for kind, data in srv.events(run=run_id):
        if kind == "approval" and data["state"] == "pending":
            assert srv.client.post(f"/api/runs/{run_id}/cancel").status_code == 202
    assert srv.client.get(f"/api/runs/{run_id}").json()["status"] == "cancelled"
    assert [a["state"] for a in srv.client.get("/api/approvals").json()] == ["withdrawn"]


def test_map_change_refreshes_the_vocabulary_and_is_streamed(server):
    c = server.client
    v1 = c.get("/api/vocabulary").json()
    cup = next(o for o in v1["objects"] if o["id"] == "blue_cup")
    assert cup["where"] == "on the kitchen table" and cup["label"] == "blue cup"
    assert {"kitchen", "bathroom"} <= {r["id"] for r in v1["rooms"]}
    assert "oven in the kitchen" in [p["name"] for p in v1["places"]]
    fetch = next(m for m in v1["missions"] if m["name"] == "fetch_test")
    assert fetch["utterances"][0]["slots"] == {"object": "thing"}
    since = c.get("/api/health").json()["last_event"]
    server.world.move_object("blue_cup", "side_table", Pose(0.0, 0.0, 0.72), source="test")
    seen = {}
    for kind, data in server.events(since=since, close_on_end=False,
                                    until=lambda k, d: k == "vocabulary"):
        seen[kind] = data
    assert seen["map"]["node"] == "blue_cup" and seen["vocabulary"]["revision"] > v1["revision"]
    v2 = c.get("/api/vocabulary").json()
    assert next(o for o in v2["objects"] if o["id"] == "blue_cup")["where"] == "on the side table"
    changes = c.get("/api/map").json()["recent_changes"]
    assert changes[0]["node"] == "blue_cup" and changes[0]["source"] == "test"
    body = c.post("/api/commands", json={"text": "where is the blue cup", "dry_run": True}).json()
    assert body["params"] == {"object": "blue_cup"}


def test_monitor_page_and_openapi_are_served(server):
    page = server.client.get("/")
    assert page.status_code == 200 and "<title>Hearth monitor</title>" in page.text
    schema = server.client.get("/openapi.json").json()
    assert {"/api/runs", "/api/commands", "/api/events", "/api/vocabulary", "/api/map",
            "/api/approvals/{request_id}", "/api/parameters/{name}"} <= set(schema["paths"])


def test_a_stream_following_one_run_is_woken_by_its_run_and_by_run_less_events_only():
    # Fifty clients each following their own run must not all be woken by every event:
    # a run's waiter is set by that run's events and by run-less ones (map, vocabulary),
    # the all-events waiter by any.
    import asyncio

    from hearth.executive.command.service import EventHub

    async def main():
        hub = EventHub()
        hub.attach_loop(asyncio.get_running_loop())

        async def settle():
            for _ in range(3):
                await asyncio.sleep(0)

        r1, r2, anything = hub.waiter("r1"), hub.waiter("r2"), hub.waiter()
        assert hub.waiter("r1") is r1
        hub.publish("status", {"status": "RUNNING"}, run="r1")
        await settle()
        assert r1.is_set() and anything.is_set() and not r2.is_set()
        assert [e[0] for e in hub.since(0, run="r2")[0]] == []
        fresh = hub.waiter("r1")
        assert fresh is not r1 and not fresh.is_set()
        hub.publish("map", {"node": "cup"})
        await settle()
        assert r2.is_set() and fresh.is_set()
        assert [e[1] for e in hub.since(0, run="r2")[0]] == ["map"]

    asyncio.run(main())


def test_a_submit_while_a_tick_holds_the_executive_is_answered_once_the_tick_is_done(server):
    # The API submits on its event loop only when nothing it needs is held; while another
    # thread holds the executive (a tick) or the map (a skill moving things), try_submit
    # does nothing and the request is served from a worker thread once the lock is free,
    # while the loop goes on answering others.
    import httpx

    ex, world = server.service.executive, server.world
    for lock in (ex._lock, world.lock):
        held, release = threading.Event(), threading.Event()

        def hold():
            with lock:
                held.set()
                release.wait(30)
        t = threading.Thread(target=hold)
        t.start()
        held.wait(10)
        before = len(server.service.runs())
        assert server.service.try_submit("fetch_test", {"object": "bowl"}) is None
        assert len(server.service.runs()) == before
        with ThreadPoolExecutor(1) as pool:
            pending = pool.submit(server.client.post, "/api/runs",
                                  json={"mission": "fetch_test", "params": {"object": "bowl"}})
            with httpx.Client(base_url=server.url, timeout=30) as other:
                assert other.get("/openapi.json").status_code == 200   # the loop is free
            assert not pending.done()
            release.set()
            r = pending.result(timeout=30)
        t.join(10)
        assert r.status_code == 201
        assert len(server.service.runs()) == before + 1
