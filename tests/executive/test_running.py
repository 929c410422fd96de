from hypothesis import HealthCheck, given, settings, strategies as st

from hearth.executive.replay import read_log, replay
from hearth.executive.testing import Script as S, load_mission_case, run_mission_case, test_skills
from py_trees.common import Status


def run(make_executive, path, scripts=(), max_ticks=10_000, **params):
    ex = make_executive(scripts)
    h = ex.submit(path, **params)
    ex.run_until_idle(max_ticks)
    return h, ex


def test_memory_sequence_resumes_at_running_child_reactive_rechecks_conditions(
        make_executive, mission_file, journal):
    path = mission_file("""
        name: x
        blackboard: {ok: true}
        tree:
          sequence:
            - skill: Act
              name: first
            - skill: Act
              name: slow
      """)
    h, _ = run(make_executive, path, [S("/x/slow", duration=0.5)])
    assert h.result.outcome == "succeeded"
    assert [e for e in journal if e[0] == "start"] == [("start", "/x/first"), ("start", "/x/slow")]


def test_reactive_sequence_halts_running_child_when_condition_fails(make_executive, mission_file):
    path = mission_file("""
        name: x
        tree:
          sequence:
            - skill: Measure
              outputs: {value: level}
            - condition: "{level} > 0.5"
            - skill: Act
              name: work
          reactive: true
      """)
    ex = make_executive([S("Measure", outcomes=["success"] * 3 + ["success"],
                           outputs={"value": 1.0}), S("/x/work", duration=10)])
    h = ex.submit(path)
    ex.tick(); ex.tick()
    work = ex.current_tree.nodes["/x/work"]
    assert work.status.value == "RUNNING"
    ex.make_skill.scripts[0].outputs["value"] = 0.0
    ex.run_until_idle(100)
    assert h.result.outcome == "failed" and work.halts == 1


def test_selector_falls_back_and_retry_counts_attempts(make_executive, mission_file):
    path = mission_file("""
        name: x
        tree:
          selector:
            - retry: {skill: Act, name: flaky}
              times: 3
            - skill: Act
              name: fallback
      """)
    h, ex = run(make_executive, path, [S("/x/retry/flaky", outcomes=["failure", "failure", "success"])])
    assert h.result.outcome == "succeeded"
    h2, _ = run(make_executive, path, [S("/x/retry/flaky", outcomes=["failure"])])
    assert h2.result.outcome == "succeeded"   # the fallback


def test_parallel_policies(make_executive, mission_file):
    for policy, outcomes, expected in [("all", ["success", "failure", "success"], "failed"),
                                       ("one", ["failure", "success", "failure"], "succeeded"),
                                       ("threshold", ["success", "failure", "success"], "succeeded"),
                                       ("threshold", ["success", "failure", "failure"], "failed")]:
        extra = "threshold: 2" if policy == "threshold" else ""
        path = mission_file(f"""
            name: x
            tree:
              parallel:
                - {{skill: Act, name: a}}
                - {{skill: Act, name: b}}
                - {{skill: Act, name: c}}
              policy: {policy}
              {extra}
          """)
        scripts = [S(f"/x/{n}", outcomes=[o], duration=0.1 * i) for i, (n, o) in
                   enumerate(zip("abc", outcomes))]
        h, _ = run(make_executive, path, scripts)
        assert h.result.outcome == expected, (policy, outcomes)


def test_timeout_uses_the_simulated_clock(make_executive, mission_file):
    path = mission_file("""
        name: x
        tree:
          timeout: {skill: Act, name: slow}
          seconds: 1.0
      """)
    h, _ = run(make_executive, path, [S("*/slow", duration=5)])
    assert h.result.outcome == "failed" and "timed out" in h.result.reason
    assert abs(h.result.duration - 1.0) < 0.11


def test_decorators_repeat_inverter_force(make_executive, mission_file, journal):
    path = mission_file("""
        name: x
        tree:
          sequence:
            - repeat: {skill: Act, name: thrice}
              times: 3
            - inverter: {fail: nope}
            - force_success: {skill: Act, name: bad}
            - force_failure: {skill: Act, name: good}
      """)
    h, _ = run(make_executive, path, [S("*/bad", outcomes=["failure"])])
    assert h.result.outcome == "failed" and "/x/force_failure" in h.result.reason
    assert sum(1 for e in journal if e == ("start", "/x/repeat/thrice")) == 3


def test_for_each_until_success_searches_positions(make_executive, mission_file):
    path = mission_file("""
        name: x
        parameters:
          places: {type: list, items: node_id, default: [a, b, c]}
        tree:
          for_each:
            skill: Navigate
            inputs: {target: "{place}"}
          in: $places
          as: place
          until: success
      """)
    h, ex = run(make_executive, path, [S("Navigate", outcomes=["failure", "success"])])
    nav = ex.make_skill.made["/x/Navigate"]
    assert h.result.outcome == "succeeded"
    assert [s["target"] for s in nav.seen_inputs] == ["a", "b"]
    assert h.result.outputs["place"] == "b"


def test_guard_halts_child_when_condition_stops_holding(make_executive, mission_file):
    path = mission_file("""
        name: x
        parameters:
          mode: {type: string, default: go, runtime: true}
        tree:
          guard: {skill: Act, name: work}
          while: "$mode == go"
      """)
    ex = make_executive([S("*/work", duration=10)])
    h = ex.submit(path)
    for _ in range(3):
        ex.tick()
    ex.set_parameter("mode", "stop")
    ex.run_until_idle(100)
    assert h.result.outcome == "failed" and ex.make_skill.made["/x/work"].halts == 1


def test_state_machine_follows_outcomes_smach_style(make_executive, mission_file, journal):
    path = mission_file("""
        name: x
        tree:
          state_machine:
            initial: look
            states:
              look:
                do: {skill: Act, name: look}
                transitions: {success: grab, failure: look_again}
              look_again:
                do: {skill: Act, name: look_again}
                transitions: {success: grab, failure: gave_up}
              grab:
                do: {skill: Act, name: grab}
                transitions: {success: done, failure: gave_up}
            outcomes: {done: success, gave_up: failure}
      """)
    h, ex = run(make_executive, path, [S("*/look", outcomes=["failure"])])
    assert h.result.outcome == "succeeded"
    assert [p for k, p in journal if k == "start"] == ["/x/look", "/x/look_again", "/x/grab"]
    assert ex.make_skill.made  # built


def test_halting_terminates_deepest_first(make_executive, mission_file, journal):
    path = mission_file("""
        name: x
        tree:
          sequence:
            - retry:
                sequence:
                  - skill: Act
                    name: inner
              times: 2
      """)
    ex = make_executive([S("*/inner", duration=10)])
    h = ex.submit(path)
    ex.tick()
    order = []
    tree = ex.current_tree
    for p, node in tree.nodes.items():
        orig = node.terminate
        node.terminate = (lambda o, p: lambda s: (order.append(p), o(s)))(orig, p)
    h.cancel()
    ex.run_until_idle(10)
    assert order == ["/x/retry/sequence/inner", "/x/retry/sequence", "/x/retry", "/x"]
    assert h.result.outcome == "cancelled"


class FakeRobot:
    def __init__(self):
        self.stops = 0
        self.said = []

    def say(self, text):
        self.said.append(text)

    def stop(self):
        self.stops += 1


def test_cancel_waits_for_halting_skill_then_stops_robot(make_executive, mission_file):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    robot = FakeRobot()
    ex = make_executive([S("*/drive", duration=10, halt_duration=0.5)], robot=robot)
    h = ex.submit(path)
    ex.tick(); ex.tick()
    assert h.cancel() is True
    ex.tick()
    assert h.status == "halting" and not h.done
    assert h.cancel() is True            # a cancel during a cancel: accepted, still one stop
    ex.run_until_idle(100)
    assert h.status == "cancelled" and robot.stops == 1
    assert 0.4 < h.result.duration - 0.2 < 0.7
    assert h.cancel() is False           # after the end: handled, not an error


def test_cancel_while_queued_during_startup_and_twice(make_executive, mission_file):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=10)])
    first = ex.submit(path)
    queued = ex.submit(path)
    assert queued.cancel() and queued.status == "cancelled"
    assert first.cancel() is True and first.cancel() is False   # second: already ended
    assert first.status == "cancelled"


def test_cancel_during_startup_is_not_lost(mission_file, tmp_path):
    from hearth.executive.executive import Executive
    from hearth.executive.testing import Act
    from hearth.robot.clock import SimClock
    handles = []

    class CancelsDuringSetup(Act):
        def setup(self, **kwargs):
            super().setup(**kwargs)
            assert handles[0].cancel() is True      # the mission is starting up right now

    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = Executive(clock=SimClock(), skills=test_skills(), runs_dir=None, background=False,
                   make_skill=lambda spec, b: CancelsDuringSetup(name=spec.name, bindings=b))
    handles.append(ex.submit(path))
    ex.run_until_idle(100)
    assert handles[0].status == "cancelled" and handles[0].result.ticks == 0


def test_higher_priority_preempts_equal_priority_queues(make_executive, mission_file):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=1.0)])
    low = ex.submit(path, priority=0)
    ex.tick(); ex.tick()
    same = ex.submit(path, priority=0)
    high = ex.submit(path, priority=5)
    ex.run_until_idle(1000)
    assert low.status == "preempted" and "preempted by x" in low.result.reason
    assert high.status == "succeeded" and same.status == "succeeded"


def test_background_thread_runs_and_wait_returns_result(make_executive, mission_file):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=2.0)], background=True)
    h = ex.submit(path)
    result = h.wait(timeout=30)
    assert result is not None and result.outcome == "succeeded"


def test_map_updates_are_forwarded_as_events(make_executive, mission_file):
    class World:
        def subscribe(self, cb):
            self.cb = cb
            return lambda: None

    class Change:
        time, node, field, old, new, source = 1.0, "cup", "parent", "table", "shelf", "test"

    world = World()
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=1.0)], world=world)
    h = ex.submit(path)
    seen = []
    h.subscribe(seen.append)
    ex.tick()
    world.cb(Change())
    ex.run_until_idle(100)
    maps = [e for e in seen if e.kind == "map"]
    assert maps and maps[0].data["node"] == "cup" and maps[0].data["new"] == "shelf"


def test_go_to_rest_follows_presence_change_mid_run(make_executive):
    robot = FakeRobot()
    ex = make_executive([S("NavigateTo", duration=3.0, halt_duration=0.3)], robot=robot,
                        skills=None)
    ex.skills = None
    h = ex.submit("missions/go_to_rest.yaml", presence="home", rest_near_user="side_table",
                  rest_out_of_the_way="kitchen_table")
    for _ in range(10):
        ex.tick()
    ex.set_parameter("presence", "away")
    ex.run_until_idle(1000)
    sub = ex.make_skill
    assert h.result.outcome == "succeeded"
    near = sub.made["/follow_presence/choose_rest_place/user_home/near_user/drive_near_user"]
    away = sub.made["/follow_presence/choose_rest_place/user_away/drive_out_of_the_way"]
    assert near.halts == 1 and away.seen_inputs == [{"target": "kitchen_table", "parking": None,
                                                     "near": None, "distance": None}]
    assert robot.said == [] and robot.stops == 0
    assert ex.current is None
    # the restart waited for the halted drive to stop, and replay reproduces that too
    _, events, _ = read_log(h.log_path)
    restart = next(e["tick"] for e in events if e["e"] == "restart")
    stopped = next(e["tick"] for e in events if e["e"] == "stopped")
    assert stopped - restart == 3
    report = replay(h.log_path)
    assert report.same, report.first_difference()


def test_execution_log_replays_to_the_same_timeline(make_executive, mission_file):
    path = mission_file("""
        name: x
        parameters:
          mode: {type: string, default: a, runtime: true}
        tree:
          sequence:
            - watch:
                retry: {skill: Measure, name: m, outputs: {value: v}}
                times: 3
              params: [mode]
            - condition: "{v} > 1"
            - timeout: {skill: Act, name: slow}
              seconds: 0.5
      """)
    ex = make_executive([S("*/m", outcomes=["failure", "success"], duration=0.2,
                           outputs={"value": 2.0}), S("*/slow", duration=2)])
    h = ex.submit(path)
    for _ in range(3):
        ex.tick()
    ex.set_parameter("mode", "b")
    ex.run_until_idle(1000)
    header, events, end = read_log(h.log_path)
    assert end["outcome"] == h.result.outcome == "failed"
    report = replay(h.log_path, test_skills())
    assert report.same, report.first_difference()
    assert any(e["e"] == "restart" for e in events)


def test_cancelled_run_replays_too(make_executive, mission_file):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=10, halt_duration=0.3)])
    h = ex.submit(path)
    ex.tick(); ex.tick()
    h.cancel()
    ex.run_until_idle(100)
    report = replay(h.log_path, test_skills())
    assert report.same, report.first_difference()


def test_test_mission_reports_never_ticked_nodes(mission_file, tmp_path, capsys):
    from hearth.cli.main import main
    case = tmp_path / "case.yaml"
    case.write_text("params: {presence: away}\nsubstitute:\n  - {match: NavigateTo, duration: 1}\n"
                    "expect: succeeded\n")
    assert main(["test-mission", "missions/go_to_rest.yaml", "--substitute", str(case)]) == 0
    out = capsys.readouterr().out
    assert "never ticked: /follow_presence/choose_rest_place/user_home/near_user/drive_near_user" in out
    report = run_mission_case("missions/go_to_rest.yaml", load_mission_case(case))
    # away: the near-user branch (its sequence, RestPlace, the drive, the announcement), its
    # fall-back (sequence, force_success, the drive, the give-up) and the away give-up never run
    assert report.outcome == "succeeded" and len(report.never_ticked) == 9


# -- property: random trees load and either finish or are cancelled, every node terminated --
LEAF = st.builds(lambda o, d: {"skill": "Act", "_o": o, "_d": d},
                 st.sampled_from(["success", "failure"]), st.sampled_from([0.0, 0.1, 0.3]))


def _tree(children):
    return st.one_of(
        st.builds(lambda c, r: {"sequence": c, "reactive": r}, st.lists(children, min_size=1, max_size=3), st.booleans()),
        st.builds(lambda c, r: {"selector": c, "reactive": r}, st.lists(children, min_size=1, max_size=3), st.booleans()),
        st.builds(lambda c: {"parallel": c, "policy": "one"}, st.lists(children, min_size=1, max_size=3)),
        st.builds(lambda c: {"retry": c, "times": 2}, children),
        st.builds(lambda c: {"inverter": c}, children),
        st.builds(lambda c: {"timeout": c, "seconds": 0.2}, children),
    )


TREES = st.recursive(LEAF, _tree, max_leaves=8)


@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
@given(TREES, st.integers(min_value=0, max_value=6), st.booleans())
def test_random_trees_finish_or_cancel_with_every_node_terminated(make_executive, tmp_path_factory,
                                                                   tree, cancel_tick, cancel):
    import yaml
    scripts, counter = [], [0]

    def name_leaves(node):
        if "skill" in node:
            counter[0] += 1
            name = f"leaf{counter[0]}"
            scripts.append(S(f"*/{name}", outcomes=[node.pop("_o")], duration=node.pop("_d")))
            node["name"] = name
            return
        for k in ("sequence", "selector", "parallel"):
            for c in node.get(k, []):
                name_leaves(c)
        for k in ("retry", "inverter", "timeout"):
            if k in node:
                name_leaves(node[k])

    name_leaves(tree)
    path = tmp_path_factory.mktemp("rt") / "m.yaml"
    path.write_text(yaml.safe_dump({"name": "r", "tree": tree}))
    ex = make_executive(scripts, runs_dir=None)
    h = ex.submit(str(path))
    for _ in range(cancel_tick):
        ex.tick()
    nodes = list(ex.current_tree.root.iterate()) if ex.current_tree else []
    if cancel:
        h.cancel()
    ex.run_until_idle(300)
    if not h.done:   # e.g. a reactive sequence restarting slow children forever: cancel it
        assert h.cancel() is True
        ex.run_until_idle(1000)
    assert h.done and h.status in ("succeeded", "failed", "cancelled")
    assert all(n.status.value != "RUNNING" for n in nodes)


def test_a_skill_that_raises_fails_the_mission_with_the_reason(make_executive, mission_file):
    from hearth.executive.testing import Act

    class Broken(Act):
        def update(self):
            raise RuntimeError("gripper on fire")

    path = mission_file("name: x\ntree: {skill: Act, name: act}\n")
    ex = make_executive()
    ex.make_skill = lambda spec, b: Broken(name=spec.name, bindings=b)
    h = ex.submit(path)
    ex.run_until_idle(10)
    assert h.status == "failed" and "gripper on fire" in h.result.reason


def test_log_show_and_replay_commands(make_executive, mission_file, capsys):
    from hearth.cli.main import main
    path = mission_file("name: x\ntree: {skill: Act, name: act}\n")
    ex = make_executive([S("*/act", duration=0.3)])
    h = ex.submit(path)
    ex.run_until_idle(100)
    assert main(["log", "show", h.log_path]) == 0
    out = capsys.readouterr().out
    assert "status  /act INVALID -> RUNNING" in out and "end     succeeded" in out


def test_step_ticks_and_prints_tree_with_statuses(make_executive, mission_file):
    import io
    from hearth.cli.commands.step import Stepper
    path = mission_file("""
        name: x
        tree:
          sequence:
            - {skill: Act, name: a}
            - {skill: Act, name: b}
      """)
    ex = make_executive([S("*/a", duration=0.2), S("*/b", duration=0.2)])
    h = ex.submit(path)
    st = Stepper(ex, h, out=io.StringIO())
    assert st.until("b") is True
    tree = st.tree()
    assert "+ |-- Act a" in tree and "* `-- Act b" in tree
    st.tick(100)
    assert h.status == "succeeded"


def test_for_each_over_an_empty_list_never_ticks_its_child(make_executive, mission_file):
    for until, expected in (("failure", "succeeded"), ("success", "failed")):
        path = mission_file(f"""
            name: x
            tree:
              for_each: {{skill: Navigate, inputs: {{target: "{{place}}"}}}}
              in: []
              as: place
              until: {until}
          """)
        h, ex = run(make_executive, path)
        assert h.result.outcome == expected
        assert ex.make_skill.made["/x/Navigate"].activations == 0


def test_concurrent_submits_and_cancels_from_other_threads_all_end(make_executive, mission_file):
    import random
    import threading
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=0.5, halt_duration=0.2)], background=True,
                        runs_dir=None)
    rng = random.Random(7)
    handles, lock = [], threading.Lock()

    def client(seed):
        r = random.Random(seed)
        for _ in range(15):
            h = ex.submit(path, priority=r.randint(0, 2))
            with lock:
                handles.append(h)
            if r.random() < 0.5:
                h.cancel()

    threads = [threading.Thread(target=client, args=(rng.random(),)) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for h in handles:
        assert h.wait(timeout=60) is not None, h
    assert {h.status for h in handles} <= {"succeeded", "cancelled", "preempted"}
    assert ex.idle()


def test_a_queued_mission_starts_with_the_latest_runtime_value(make_executive, mission_file):
    path = mission_file("""
        name: x
        parameters:
          presence: {type: string, default: home, runtime: true}
        tree: {skill: Speak, inputs: {text: $presence}, name: say}
      """)
    ex = make_executive([S("*/say", duration=0.5)])
    first = ex.submit(path)
    second = ex.submit(path)
    ex.tick()
    ex.set_parameter("presence", "away")     # reaches the running one and the queued one
    ex.run_until_idle(100)
    assert first.status == second.status == "succeeded"
    assert second.params["presence"] == "away"


def test_set_parameter_checks_the_type_declared_by_running_and_queued_missions(
        make_executive, mission_file):
    import pytest
    from hearth.executive.errors import MissionError
    path = mission_file("""
        name: x
        parameters:
          level: {type: number, default: 1, runtime: true}
        tree: {succeed: ok}
      """)
    ex = make_executive()
    ex.submit(path)
    with pytest.raises(MissionError, match="parameter level: expected number"):
        ex.set_parameter("level", "high")
    ex.set_parameter("unrelated", "anything")   # declared by no mission: kept for later ones
    assert ex.parameters == {"unrelated": "anything"}


def test_a_terminate_that_raises_does_not_keep_others_from_halting(make_executive, mission_file):
    from hearth.executive.testing import Act

    class BadStop(Act):
        def terminate(self, new_status):
            super().terminate(new_status)
            if new_status.value == "INVALID":
                raise RuntimeError("stuck")

    path = mission_file("""
        name: x
        tree:
          parallel:
            - {skill: Act, name: bad}
            - {skill: Act, name: good}
      """)
    robot = FakeRobot()
    ex = make_executive(robot=robot)
    made = {}

    def make(spec, b):
        cls = BadStop if spec.name == "bad" else Act
        cls = type(cls.__name__, (cls,), {"script": S(duration=10)})
        made[spec.name] = cls(name=spec.name, bindings=b)
        return made[spec.name]
    ex.make_skill = make
    h = ex.submit(path)
    ex.tick(); ex.tick()
    h.cancel()
    ex.run_until_idle(100)
    assert h.status == "cancelled" and robot.stops == 1
    assert made["good"].halts == 1 and made["good"].status.value == "INVALID"


def test_missions_above_the_granted_autonomy_are_refused(make_executive, mission_file):
    import pytest
    from hearth.executive.errors import MissionValidationError
    ex = make_executive(autonomy=0, skills=None)
    with pytest.raises(MissionValidationError) as err:
        ex.submit("missions/go_to_rest.yaml")
    assert "skill NavigateTo acts with autonomy 1, above the granted level 0" in str(err.value)
    assert str(err.value).startswith("missions/go_to_rest.yaml:")


def test_every_decorator_and_container_halts_deepest_first(make_executive, mission_file):
    path = mission_file("""
        name: x
        parameters:
          mode: {type: string, default: a, runtime: true}
        blackboard: {items: [1, 2]}
        tree:
          parallel:
            - watch:
                guard:
                  timeout:
                    for_each:
                      retry:
                        repeat: {skill: Act, name: deep1}
                        times: 2
                      times: 2
                    in: "{items}"
                    as: item
                  seconds: 100
                while: "$mode == a"
              params: [mode]
            - state_machine:
                initial: s
                states:
                  s:
                    do:
                      include: sub
                    transitions: {success: done, failure: done}
                outcomes: {done: success}
            - inverter: {force_success: {force_failure: {skill: Act, name: deep3}}}
        subtrees:
          sub:
            tree: {sequence: [{selector: [{skill: Act, name: deep2}], reactive: true}]}
      """)
    ex = make_executive([S("*/deep*", duration=100)])
    h = ex.submit(path)
    ex.tick(); ex.tick()
    tree = ex.current_tree
    order = []
    for p, node in tree.nodes.items():
        node.terminate = (lambda o, p: lambda s: (order.append(p), o(s)))(node.terminate, p)
    running = {p for p, n in tree.nodes.items() if n.status.value == "RUNNING"}
    h.cancel()
    ex.run_until_idle(10)
    assert h.status == "cancelled"
    assert running <= set(order) and len(running) > 15
    for i, p in enumerate(order):
        later_descendants = [q for q in order[i + 1:] if q.startswith(p + "/")]
        assert not later_descendants, f"{p} terminated before {later_descendants}"


def test_wall_clock_runs_replay_at_their_logged_tick_times(tmp_path, mission_file):
    import random
    from hearth.executive.executive import Executive
    from hearth.executive.testing import Substitution

    class ManualWallClock:
        simulated = False

        def __init__(self):
            self.t = 100.0

        def now(self):
            return self.t

        def wall(self):
            return 1.7e9 + self.t

        def sleep(self, s):
            self.t += s

    path = mission_file("""
        name: x
        tree:
          sequence:
            - timeout: {skill: Act, name: a}
              seconds: 0.5
            - timeout: {skill: Act, name: b}
              seconds: 0.5
      """)
    clock = ManualWallClock()
    ex = Executive(clock=clock, runs_dir=str(tmp_path), skills=test_skills(), background=False,
                   make_skill=Substitution([S("*/a", duration=0.3), S("*/b", duration=0.45)]))
    h = ex.submit(path)
    rng = random.Random(3)
    while not h.done:
        ex.tick()
        clock.t += rng.uniform(0.05, 0.2)     # irregular real tick periods
    report = replay(h.log_path, test_skills())
    assert report.same, report.first_difference()


def test_example_case_file_for_go_to_rest(tmp_path, capsys):
    from hearth.cli.main import main
    case = "tests/executive/cases/go_to_rest_presence_change.yaml"
    assert main(["test-mission", "missions/go_to_rest.yaml", "--substitute", case,
                 "--runs-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "outcome: succeeded (completed) after 45 ticks, 4.40 s simulated" in out
    assert "never ticked: /follow_presence/choose_rest_place/user_home/near_user/announce" in out
    (log,) = tmp_path.glob("*.jsonl")
    assert main(["log", "replay", str(log)]) == 0


def test_bad_substitution_file_is_one_line_with_file_and_line(tmp_path, capsys):
    from hearth.cli.main import main
    case = tmp_path / "case.yaml"
    case.write_text("substitute:\n  - {match: NavigateTo, outcome: maybe}\n")
    assert main(["test-mission", "missions/go_to_rest.yaml", "--substitute", str(case)]) == 2
    assert capsys.readouterr().err.strip() == \
        f"{case}:2: script NavigateTo: outcome 'maybe' is not success or failure"


def test_state_machine_transitions_on_a_named_outcome_from_a_key(make_executive, mission_file,
                                                                  journal):
    path = mission_file("""
        name: x
        tree:
          state_machine:
            initial: look
            states:
              look:
                do: {skill: Act, name: look, outputs: {result: verdict}}
                outcome: "{verdict}"
                transitions: {found: grab, ambiguous: move, failure: gave_up}
              move:
                do: {skill: Act, name: move}
                transitions: {success: look, failure: gave_up}
              grab:
                do: {skill: Act, name: grab}
                transitions: {success: done, failure: gave_up}
            outcomes: {done: success, gave_up: failure}
      """)
    verdicts = iter(["ambiguous", "ambiguous", "found"])   # per tick; a look spans 2 ticks
    script = S("*/look", duration=0.1)        # one look per tick, one verdict per look
    ex = make_executive([script])
    h = ex.submit(path)
    while not h.done:
        script.outputs = {"result": next(verdicts, "found")}
        ex.tick()
    assert h.result.outcome == "succeeded"
    assert [p for k, p in journal if k == "start"] == ["/x/look", "/x/move", "/x/look", "/x/grab"]
    # an outcome nobody mapped fails the block, saying which
    ex2 = make_executive([S("*/look", outputs={"result": "exploded"})])
    h2 = ex2.submit(path)
    ex2.run_until_idle(100)
    assert h2.result.outcome == "failed" and "unmapped outcome 'exploded'" in h2.result.reason


def test_a_user_cancel_during_a_preempt_wins(make_executive, mission_file):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    ex = make_executive([S("*/drive", duration=1.0, halt_duration=0.5)])
    low = ex.submit(path)
    ex.tick(); ex.tick()
    high = ex.submit(path, priority=1)
    ex.tick()
    assert low.status == "halting"
    assert low.cancel("user said stop") is True
    ex.run_until_idle(1000)
    assert low.status == "cancelled" and low.result.reason == "user said stop"
    assert high.status == "succeeded"


# -- the cancel promise: reported only once what the mission started has stopped ------------
def _braking_skill(stops_on_robot_stop: bool, robot):
    """A stand-in drive that keeps reporting is_halting() after it is halted: for ever, or
    until ``robot.stop()`` is called."""
    from hearth.executive.testing import Act

    class Braking(Act):
        HALT_TIMEOUT = 0.5

        def update(self):
            self.feedback_message = "driving"
            return Status.RUNNING

        def terminate(self, new_status):
            self.stops_seen = robot.stops

        def is_halting(self):
            return not (stops_on_robot_stop and robot.stops > self.stops_seen)
    return Braking


def test_a_skill_that_never_confirms_it_stopped_ends_the_cancel_saying_so(make_executive,
                                                                          mission_file):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    robot = FakeRobot()
    ex = make_executive(robot=robot)
    Braking = _braking_skill(False, robot)
    ex.make_skill = lambda spec, b: Braking(name=spec.name, bindings=b)
    h = ex.submit(path)
    ex.tick(); ex.tick()
    h.cancel("user said stop")
    for _ in range(3):
        ex.tick()
    assert h.status == "halting" and robot.stops == 0      # waiting for the skill, not yet
    ex.run_until_idle(100)
    r = h.result
    assert r.outcome == "cancelled" and r.robot_stopped is False and robot.stops == 1
    assert r.reason == ("cancelled, robot not confirmed stopped (/drive still stopping "
                        "after 0.5 s): user said stop")
    _, events, end = read_log(h.log_path)
    assert end["robot_stopped"] is False and end["reason"] == r.reason
    assert events[-1]["e"] == "run" and events[-1]["robot_stopped"] is False
    halted = next(e for e in events if e["e"] == "halted")
    assert halted["timed_out"] == ["/drive"] and halted["waited"] == 0.5
    assert replay(h.log_path, test_skills()).same


def test_a_skill_that_robot_stop_stops_confirms_the_cancel(make_executive, mission_file):
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    robot = FakeRobot()
    ex = make_executive(robot=robot)
    Braking = _braking_skill(True, robot)
    ex.make_skill = lambda spec, b: Braking(name=spec.name, bindings=b)
    runs = []
    ex.subscribe(lambda e: runs.append((e.run, e.data["state"])) if e.kind == "run" else None)
    low = ex.submit(path)
    ex.tick(); ex.tick()
    high = ex.submit(path, priority=1)
    ex.run_until_idle(20)
    assert low.result.outcome == "preempted" and low.result.robot_stopped is True
    assert low.result.reason == f"preempted by x ({high.id})"
    _, events, end = read_log(low.log_path)
    assert "robot_stopped" not in end and [e["e"] for e in events][-3:] == ["stopped", "halted",
                                                                            "run"]
    # the preempting mission started only after the preempted one had ended
    assert runs == [(low.id, "running"), (low.id, "halting"), (low.id, "preempted"),
                    (high.id, "running")]


def test_a_failing_log_write_ends_the_run_instead_of_leaving_it_stuck(make_executive,
                                                                      mission_file):
    from hearth.executive.runlog import RunLog
    path = mission_file("name: x\ntree: {skill: Act, name: drive}\n")
    robot = FakeRobot()
    ex = make_executive([S("*/drive", duration=1.0)], robot=robot)
    h = ex.submit(path)
    ex.tick()
    real = RunLog.flush

    def disk_full(self):
        raise OSError(28, "No space left on device")
    RunLog.flush = disk_full
    try:
        ex.run_until_idle(100)
    finally:
        RunLog.flush = real
    assert h.done and h.status == "failed" and ex.idle()
    assert h.result.reason.startswith("internal error: OSError: [Errno 28] No space left")
    assert robot.stops == 1


def test_lifecycles_share_one_machine_and_refuse_transitions_it_lacks():
    # Every run's lifecycle is a model of one transitions machine: each keeps its own state,
    # a trigger from a state the table does not list raises, and the machine keeps no
    # reference to the runs (none is kept alive by it).
    from transitions import MachineError
    from hearth.executive.scheduler import MACHINE, Lifecycle

    a, b = Lifecycle(), Lifecycle()
    assert (a.state, b.state) == ("queued", "queued")
    a.start()
    a.halt()
    b.cancel_queued()
    assert (a.state, b.state) == ("halting", "cancelled")
    a.end_preempt()
    assert a.state == "preempted"
    for life, trigger in [(b, "start"), (a, "end_cancel"), (Lifecycle(), "succeed"),
                          (Lifecycle(), "halt")]:
        state = life.state
        try:
            getattr(life, trigger)()
        except MachineError:
            pass
        else:
            raise AssertionError(f"{trigger} from {state} was accepted")
        assert life.state == state
    c = Lifecycle()
    c.fail()
    assert c.state == "failed"
    assert MACHINE.models == []
