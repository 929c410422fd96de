"""The day over the command API (hearth serve --schedule): emergencies, battery levels, away,
and day events on the event stream. A simulated robot on a simulated clock."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from hearth.executive.command.api import _check_token, create_app
from hearth.executive.command.day_api import day_router
from hearth.executive.command.server import make_service
from hearth.executive.day import Day, Schedule
from hearth import demo_world_path, missions_dir
from hearth.robot.clock import SimClock
from hearth.robot.simulated import SimulatedRobot
from hearth.worldmodel.io import load_world


@pytest.fixture
def served():
    world = load_world(str(demo_world_path()))
    clock = SimClock()
    robot = SimulatedRobot(world.copy(), clock=clock, noise=None, person_room="bathroom")
    service = make_service(world, robot, [str(missions_dir())], clock=clock, runs_dir=None)

    def submit(name, params, priority, source):
        return service.submit(name, params, priority, source=source)[0].handle
    day = Day(service.executive, robot, {n: e.mission for n, e in
                                         service.vocabulary.catalogue.items()},
              Schedule(()), on_event=lambda e: service.hub.publish("day", e), submit=submit)
    app = create_app(service)
    app.include_router(day_router(day, _check_token(None)))
    with TestClient(app, base_url="http://localhost") as client:
        yield client, service, day
    day.close()
    service.executive.shutdown()
    service.close()


def test_an_emergency_over_the_api_sends_the_robot_to_the_user(served):
    client, service, day = served
    r = client.post("/api/day/emergency", json={"user_room": "bathroom"})
    assert r.status_code == 200 and r.json()["waits_for_charge"] is False
    run = r.json()["run"]
    result = service.run(run).handle.wait(30)
    assert result is not None and result.outcome == "succeeded"
    listed = client.get(f"/api/runs/{run}").json()
    assert listed["mission"] == "go_to_user" and listed["priority"] == 100
    state = client.get("/api/day").json()
    assert state["report"]["emergencies"] == 1
    assert state["report"]["emergency_response_s_median"] <= 2.0
    kinds = [e[1] for e in service.hub.since(0, limit=10_000)[0]]
    assert "day" in kinds


def test_battery_levels_are_set_at_run_time_and_checked(served):
    client, service, day = served
    assert client.put("/api/day/battery", json={"low": 0.4}).json()["low"] == 0.4
    assert day.battery.low == 0.4
    bad = client.put("/api/day/battery", json={"low": 0.1})
    assert bad.status_code in (400, 422)
    assert "critical (0.15) < low (0.1)" in bad.json()["error"]["message"]
    assert client.put("/api/day/away", json={"away": True}).json() == {"away": True}
    assert day.away is True
