"""Event kinds, the run log's two ways of writing a line, delivery to subscribers outside
the executive's lock, and the log of every submitted run."""
from __future__ import annotations

import json
import threading

from py_trees import common

from hearth.executive.events import EventKind, RunState
from hearth.executive.replay import read_log, replay
from hearth.executive.runlog import RunLog, status_event
from hearth.executive.testing import Act, Script as S, test_skills

Status = common.Status


def test_event_kinds_and_states_read_as_their_strings():
    assert EventKind.STATUS == "status" and "status" in {EventKind.STATUS}
    assert EventKind.MAP in {"tick", "map"} and RunState.CANCELLED in ("cancelled",)
    assert f"{EventKind.RUN} {RunState.PREEMPTED}" == "run preempted"
    assert json.dumps({"e": EventKind.HALTED, "state": RunState.HALTING}) == \
        '{"e": "halted", "state": "halting"}'


def test_hot_path_status_lines_are_the_bytes_of_event_to_json(tmp_path):
    runs = ["20240101T000000-x-0", 'odd "id" \\ é']
    paths = ["/x", "/x/a b/ü", '/x/"q"\\n']
    times = [0.0, 0.1 + 0.2, 1e-10, 12345.123456789012, 3.0000000004]
    for run_id in runs:
        hot = RunLog(tmp_path / "hot.jsonl", run_id)
        generic = RunLog(tmp_path / "generic.jsonl", run_id)
        for tick, now in enumerate(times):
            hot.begin_tick(tick, now)
            for path in paths:
                for st in Status:
                    for prev in Status:
                        for halted in (False, True):
                            hot.status(json.dumps(path), st, prev, halted)
                            generic.event(status_event(run_id, tick, now, path, st, prev, halted))
        hot.close()
        generic.close()
        hot_bytes = (tmp_path / "hot.jsonl").read_bytes()
        assert hot_bytes == (tmp_path / "generic.jsonl").read_bytes()
        assert hot_bytes.count(b"\n") == len(times) * len(paths) * 4 * 4 * 2


def test_subscribers_are_called_without_the_executive_lock(make_executive, mission_file):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=0.3)])
    h = ex.submit(path)
    answered = []

    def subscriber(event):
        # Another thread takes the executive's lock: it can only if this call does not hold it.
        other = threading.Thread(target=lambda: answered.append(ex.idle()))
        other.start()
        other.join(timeout=10)
        assert not other.is_alive(), "the executive lock was held while calling a subscriber"

    h.subscribe(subscriber)
    ex.run_until_idle(100)
    assert h.result.outcome == "succeeded" and len(answered) >= 4


def test_a_slow_subscriber_stalls_neither_ticks_nor_callers(make_executive, mission_file):
    ticked, release = threading.Event(), threading.Event()

    class Counts(Act):
        def update(self):
            self.n = getattr(self, "n", 0) + 1
            if self.n == 20:
                ticked.set()          # the mission got 20 ticks further
            return Status.SUCCESS if self.n >= 25 else Status.RUNNING

    path = mission_file("name: x\ntree: {skill: Act, name: count}\n")
    ex = make_executive(background=True)
    ex.make_skill = lambda spec, b: Counts(name=spec.name, bindings=b)
    seen = []

    def slow(event):
        seen.append(event)
        release.wait(30)              # stuck until the test lets it go

    ex.subscribe(slow)
    h = ex.submit(path)
    try:
        assert ticked.wait(30), "ticking stalled behind a slow subscriber"
        assert ex.queued == [] and ex.parameters == {}     # the lock is free too
        assert not h.done      # done only once its subscribers have had the last event
    finally:
        release.set()
    result = h.wait(30)
    assert result is not None and result.outcome == "succeeded"
    assert seen[-1].kind is EventKind.RUN and seen[-1].data["state"] == "succeeded"


def test_a_run_cancelled_while_queued_leaves_a_log_saying_so(make_executive, mission_file,
                                                              capsys):
    from hearth.cli.main import main
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=1.0)])
    first, queued = ex.submit(path), ex.submit(path)
    assert queued.cancel("not needed any more") is True
    ex.run_until_idle(100)
    header, events, end = read_log(queued.log_path)
    assert header["started"] is False and header["mission"] == "x"
    assert [(e["e"], e["state"]) for e in events] == [("run", "cancelled")]
    assert (end["outcome"], end["reason"]) == ("cancelled", "not needed any more")
    assert queued.result.log_path == queued.log_path
    assert replay(queued.log_path, test_skills()).same
    assert main(["log", "show", queued.log_path]) == 0
    assert "end     cancelled: not needed any more" in capsys.readouterr().out
    assert first.result.outcome == "succeeded"


def test_every_run_a_shutdown_cancels_has_a_log_with_its_end(make_executive, mission_file,
                                                             tmp_path):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=10.0)], runs_dir=str(tmp_path / "logs"))
    handles = [ex.submit(path)]
    ex.tick()                      # the first runs, the others wait
    handles += [ex.submit(path) for _ in range(3)]
    ex.shutdown()
    logs = sorted((tmp_path / "logs").glob("*.jsonl"))
    assert len(logs) == 4 == len({h.log_path for h in handles})
    assert [read_log(h.log_path)[2]["reason"] for h in handles] == ["executive shut down"] * 4
    assert [h.result.outcome for h in handles] == ["cancelled"] * 4


def test_demo_progress_prints_run_states_and_each_skills_final_word(make_executive,
                                                                    mission_file, capsys):
    from hearth.cli.commands.demo import _Progress
    path = mission_file("""
        name: x
        tree:
          sequence:
            - retry: {skill: Act, name: drive}
              times: 2
            - condition: "$mode == a"
        parameters:
          mode: {type: string, default: a}
      """)
    ex = make_executive([S("*/drive", duration=0.3, feedback="")])
    progress = _Progress(quiet=False)
    ex.subscribe(progress)
    h = ex.submit(path)
    progress.follow(h.mission)
    ex.run_until_idle(100)
    lines = [line.split("] ", 1)[1] for line in capsys.readouterr().out.splitlines()]
    # no "Act working" while it drives, no retry or condition messages
    assert lines == ["mission running", "drive: Act scripted success",
                     "mission succeeded: completed"]
