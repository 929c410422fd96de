"""Command-layer fixtures: a real server on 127.0.0.1 (ephemeral port) over an executive
whose skills are scripted stand-ins (hearth.executive.testing), on the demo home's map."""
from __future__ import annotations

import json
import ssl
from pathlib import Path

import httpx
import pytest

from hearth.executive.command.api import create_app
from hearth.executive.command.server import ServerThread, make_service
from hearth.executive.testing import Script, ScriptedSkill, Substitution, test_skills
from hearth.robot.clock import WallClock
from hearth.skills.base import Port

MISSIONS = Path(__file__).parent / "missions"


class TurnTestKnob(ScriptedSkill):
    """A test-only skill that acts on the home (autonomy 2)."""
    NAME = "TurnTestKnob"
    AUTONOMY = 2
    INPUTS = (Port("knob", "node_id"),)


def registry() -> dict:
    reg = test_skills()
    reg[TurnTestKnob.NAME] = TurnTestKnob
    return reg


class Server:
    """A running API: ``url``, ``client`` (httpx), ``service``, ``world``."""

    def __init__(self, world, granted=3, token=None, approval_timeout=120.0, tls_cert=None,
                 tls_key=None, missions=None, **app_options):
        self.world = world
        # wait_test's first step runs for an hour (it is cancelled); the rest succeed at once.
        self.substitution = Substitution([Script(match="/wait_test/hold", duration=3600.0)], None)
        # A wall clock at 50 Hz: a running mission waits between ticks instead of spinning.
        self.service = make_service(world, None, [str(m) for m in missions or [MISSIONS]],
                                    skills=registry(),
                                    make_skill=self.substitution, clock=WallClock(),
                                    tick_hz=50, runs_dir=None, granted=granted,
                                    approval_timeout=approval_timeout)
        self.thread = ServerThread(create_app(self.service, token=token, **app_options),
                                   tls_cert=tls_cert, tls_key=tls_key).start()
        self.url = self.thread.url
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        verify = ssl.create_default_context(cafile=tls_cert) if tls_cert else True
        self.client = httpx.Client(base_url=self.url, timeout=30.0, headers=headers,
                                   verify=verify)

    def events(self, run=None, since=0, close_on_end=True, until=None):
        """Yield (kind, data) from the event stream; stops at the end of ``run`` or when
        ``until(kind, data)`` is true."""
        params = {"since": since, "close_on_end": close_on_end}
        if run:
            params["run"] = run
        with self.client.stream("GET", "/api/events", params=params) as r:
            assert r.status_code == 200
            kind = None
            for line in r.iter_lines():
                if line.startswith("event: "):
                    kind = line[7:]
                elif line.startswith("data: "):
                    data = json.loads(line[6:])
                    yield kind, data
                    if until is not None and until(kind, data):
                        return

    def close(self):
        self.client.close()
        self.thread.stop()
        self.service.executive.shutdown()
        self.service.close()


@pytest.fixture
def make_server(demo_world):
    made = []

    def make(**kw):
        s = Server(demo_world, **kw)
        made.append(s)
        return s
    yield make
    for s in made:
        s.close()


@pytest.fixture
def server(make_server):
    return make_server()
