"""Approval gates in the executive itself (simulated clock, ticked by hand)."""
from __future__ import annotations

import importlib.util
import textwrap
from pathlib import Path

from hearth.executive.autonomy import Approvals, gated_factory
from hearth.executive.executive import Executive
from hearth.executive.testing import Script, Substitution
from hearth.robot.clock import SimClock

HERE = Path(__file__).parent
_spec = importlib.util.spec_from_file_location("command_conftest_a", HERE / "conftest.py")
_conf = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_conf)

MISSION = textwrap.dedent("""\
    hearth: 1
    name: both
    tree:
      parallel:
        - skill: TurnTestKnob
          name: turn
          inputs: {knob: oven}
        - skill: Act
          name: watch
      policy: all
    """)


def _executive(tmp_path, granted, timeout=30.0):
    approvals = Approvals(granted=granted, timeout=timeout)
    sub = Substitution([Script(match="Act", duration=2.0)], None)
    ex = Executive(clock=SimClock(), tick_hz=10, runs_dir=None, skills=_conf.registry(),
                   make_skill=gated_factory(sub), background=False,
                   setup_kwargs={"approvals": approvals})
    path = tmp_path / "both.yaml"
    path.write_text(MISSION)
    return ex, approvals, sub, str(path)


def test_unanswered_request_fails_the_step_at_its_deadline_while_other_branches_run(tmp_path):
    ex, approvals, sub, path = _executive(tmp_path, granted=1, timeout=30.0)
    h = ex.submit(path)
    ex.run_until_idle(10_000)
    assert h.result.outcome == "failed"
    assert h.result.reason == ("/both/turn failed: TurnTestKnob not started: approval expired "
                               "(no answer within 30 s)")
    # The other branch was ticked meanwhile and finished (2 s) long before the deadline.
    assert sub.made["/both/watch"].activations == 1
    assert sub.made["/both/watch"].status.value == "SUCCESS"
    assert sub.made["/both/turn"].activations == 0          # the real step never started
    assert 30.0 <= h.result.duration < 30.5
    [req] = approvals.list()
    assert (req.state, req.run, req.path, req.level, req.granted) == (
        "expired", h.id, "/both/turn", 2, 1)


def test_skills_at_or_below_the_granted_level_never_ask(tmp_path):
    ex, approvals, sub, path = _executive(tmp_path, granted=2)
    h = ex.submit(path)
    ex.run_until_idle(10_000)
    assert h.result.outcome == "succeeded" and approvals.list() == []
    assert sub.made["/both/turn"].activations == 1


def test_approval_given_between_ticks_starts_the_step(tmp_path):
    ex, approvals, sub, path = _executive(tmp_path, granted=0)
    h = ex.submit(path)
    for _ in range(5):
        ex.tick()
    [req] = approvals.list(pending_only=True)
    assert req.path == "/both/turn" and sub.made["/both/turn"].activations == 0
    approvals.decide(req.id, True, by="test")
    ex.run_until_idle(10_000)
    assert h.result.outcome == "succeeded"
    assert sub.made["/both/turn"].activations == 1
