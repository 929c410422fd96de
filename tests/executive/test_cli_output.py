"""What the `hearth` commands print for a person: concise by default, every event in tick order
with --verbose, the outcome alone with --quiet, readable values, times since the start, log
names from the date of the run, no traceback when the reader of stdout goes away."""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time

import pytest

from hearth.cli.main import main
from hearth import __version__, demo_world_path


@pytest.fixture(scope="module")
def fetch(tmp_path_factory):
    """One `hearth run missions/fetch_object.yaml --param object="blue cup"` on the demo home,
    as a user runs it (its own state directory: the shipped map)."""
    tmp = tmp_path_factory.mktemp("fetch")
    env_state = tmp / "state"
    before = time.strftime("%Y%m%d", time.gmtime())
    done = subprocess.run([sys.executable, "-m", "hearth", "run", "missions/fetch_object.yaml",
                           "--param", "object=blue cup", "--runs-dir", str(tmp / "runs")],
                          capture_output=True, text=True, timeout=600,
                          env={**__import__("os").environ, "HEARTH_STATE_DIR": str(env_state)})
    after = time.strftime("%Y%m%d", time.gmtime())
    (log,) = (tmp / "runs").glob("*.jsonl")
    return done, log, {before, after}


def test_fetch_prints_under_60_short_lines_by_default(fetch):
    done, log, _ = fetch
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert len(lines) < 60, done.stdout
    assert max(len(line) for line in lines) <= 200
    assert lines[0].strip() == "0.0s  mission running: started"
    assert any(re.match(r"^ +\d+\.\ds  ok   DetectObject: blue_cup found on kitchen_table/top",
                        line) for line in lines)
    assert any(line.strip().endswith("ok   HandOver: handing over: done") for line in lines)
    assert lines[-1].startswith("fetch_object: succeeded (completed) in ")
    assert lines[-1].endswith(f"; log {log}")
    assert "%" not in done.stdout                  # no progress percentages when piped
    assert done.stderr == ""


def test_each_skill_outcome_is_printed_once(fetch):
    done, log, _ = fetch
    from hearth.executive.replay import read_log
    _, events, _ = read_log(log)
    outcomes = [e for e in events if e["e"] == "status" and e["status"] in ("SUCCESS", "FAILURE")
                and not e.get("halted") and e["path"].rsplit("/", 1)[-1] in
                ("Grasp", "HandOver", "DescribeLocation")]
    assert len(outcomes) == 3
    for name in ("Grasp", "HandOver", "DescribeLocation"):
        assert len(re.findall(rf"ok   {name}\b", done.stdout)) == 1


def test_log_names_carry_the_date_the_run_was_made(fetch):
    _, log, dates = fetch
    assert log.name[:8] in dates and log.name[8] == "T"


def test_log_show_prints_a_tick_in_the_order_it_happened(fetch, capsys):
    _, log, _ = fetch
    assert main(["log", "show", str(log)]) == 0
    lines = capsys.readouterr().out.splitlines()
    # ResolveObject wrote its outputs while it ticked, then finished: writes, then its status
    i = next(i for i, line in enumerate(lines) if "write   {object_id} = 'blue_cup'" in line)
    assert "write   {object_room} = 'kitchen'" in lines[i + 1]
    assert "write   {label} = 'blue cup'" in lines[i + 2]
    assert "status  /fetch_object/ResolveObject INVALID -> SUCCESS" in lines[i + 3]
    assert "feedbk  /fetch_object/ResolveObject: blue_cup is believed on the kitchen table" \
        in lines[i + 4]
    assert "status  /fetch_object/LocateUser INVALID -> SUCCESS" in lines[i + 7]
    # values are readable: numbers rounded, values and messages cut (the log has 2 KB lines)
    assert max(len(line) for line in lines) < 600
    assert "1.2000000000000002" not in "\n".join(lines)
    assert any("{find_object_1/known_places} = [{place: 'kitchen_table'" in line
               for line in lines)


class _Drive:
    def __init__(self, clock, seconds=1.0):
        self.clock, self.end, self.progress, self.reason = clock, clock.now() + seconds, 0.0, ""

    def status(self):
        return "succeeded" if self.clock.now() >= self.end - 1e-9 else "running"

    def cancel(self):
        pass


@pytest.fixture
def fake_robot(monkeypatch):
    from hearth import robot

    class Robot:
        def __init__(self, clock):
            self.clock = clock

        def navigate_to(self, pose):
            return _Drive(self.clock)

        def say(self, text):
            pass

        def stop(self):
            pass

    monkeypatch.setattr(robot, "create_adapter", lambda clock=None, **kw: Robot(clock),
                        raising=False)


def test_quiet_prints_the_outcome_alone_on_stdout(fake_robot, tmp_path, capsys):
    assert main(["run", "missions/go_to_rest.yaml", "--quiet", "--runs-dir", str(tmp_path)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert re.fullmatch(r"go_to_rest: succeeded \(completed\) in \d+ ticks, [\d.]+ s; log \S+\n",
                        out)


def test_verbose_prints_every_event_with_times_since_the_start(fake_robot, tmp_path, capsys):
    assert main(["run", "missions/go_to_rest.yaml", "--verbose", "--wall-clock",
                 "--tick-hz", "100", "--runs-dir", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert re.match(r"^ +0 +0\.000s  mission running: started$", lines[0])
    assert any("status  /follow_presence/choose_rest_place/user_home/near_user/drive_near_user "
               "INVALID -> RUNNING" in line for line in lines)
    times = [float(m.group(1)) for m in (re.match(r"^ +\d+ +([\d.]+)s  ", line) for line in lines)
             if m]
    assert times == sorted(times) and 1.0 <= times[-1] < 30.0      # a wall clock, from zero


def test_version_is_the_package_version(capsys):
    with pytest.raises(SystemExit) as err:
        main(["--version"])
    assert err.value.code == 0
    assert capsys.readouterr().out == f"hearth {__version__}\n"


@pytest.mark.parametrize("argv", [["map", "show", str(demo_world_path())],
                                  ["map", "find", str(demo_world_path()), "blue", "cup"]])
def test_a_closed_pipe_ends_the_command_quietly(argv):
    proc = subprocess.Popen([sys.executable, "-m", "hearth", *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()                 # `| head` that has read enough before anything came
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert err == ""


def test_bench_reports_its_progress_on_stderr(capsys):
    assert main(["bench", "worldmodel", "--quick", "--json"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("{") and out.count("\n") == 1
    assert re.search(r"^hearth bench: worldmodel running\.\.\.$", err, re.M)
    assert re.search(r"^hearth bench: worldmodel done in [\d.]+ s$", err, re.M)


def test_step_sets_a_runtime_parameter_and_stays_open_after_the_end(fake_robot, tmp_path,
                                                                   capsys, monkeypatch):
    commands = iter(["t", "s presence=away", "s presence=maybe", "s speed=3", "c", "t", "b",
                     "p", "q"])
    monkeypatch.setattr("builtins.input", lambda prompt="": next(commands))
    assert main(["step", "missions/go_to_rest.yaml", "--runs-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "$presence = 'away' from the next tick" in out
    assert "parameter presence: expected one of ['home', 'away'], got 'maybe'" in out
    assert "s NAME=VALUE sets a runtime parameter of go_to_rest (runtime: presence)" in out
    assert "restart /follow_presence: {presence: ['home', 'away']}" in out
    ended = out.index("go_to_rest: succeeded (completed); p: tree, b: blackboard, q: quit")
    after = out[ended:]
    assert "the mission has ended (succeeded)" in after        # "t" after the end
    assert "$presence            = 'away'" in after           # the blackboard, still there
    assert "watch follow_presence" in after                   # and the tree


def test_serve_on_an_ipv6_address_prints_a_bracketed_url(tmp_path):
    import signal
    import socket
    try:
        socket.socket(socket.AF_INET6).bind(("::1", 0))
    except OSError:
        pytest.skip("no IPv6 loopback here")
    # faulthandler: should the server not stop, SIGABRT makes it print every thread's stack
    proc = subprocess.Popen([sys.executable, "-m", "hearth", "serve", "--host", "::1",
                             "--port", "0", "--no-save", "--runs-dir", str(tmp_path)],
                            stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONFAULTHANDLER": "1"},
                            # Ctrl-C as a user's shell gives it, whatever an earlier test left
                            # in this process (a child inherits an ignored SIGINT)
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        line = next(line for line in proc.stderr if "http" in line)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            rest = proc.communicate(timeout=60)[1]     # read on: a full pipe blocks the server
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGABRT)
            rest = proc.communicate(timeout=30)[1]
            pytest.fail("hearth serve did not stop within 60 s of SIGINT; its threads:\n" + rest[-6000:])
    assert re.search(r"http://\[::1\]:\d+/ \(API docs at /docs\)$", line.strip()), line
    assert proc.returncode == 130 and rest.strip().splitlines()[-1].endswith("interrupted"), rest


def test_bench_turns_on_per_case_progress_where_a_benchmark_has_it(monkeypatch, capsys):
    from hearth.benchmarks import missions
    seen = []
    monkeypatch.setattr(missions, "run", lambda args: seen.append(args.verbose) or {"ok": 1})
    assert main(["bench", "missions", "--json"]) == 0
    assert main(["bench", "missions", "--json", "--no-progress"]) == 0
    assert seen == [True, False]
    err = capsys.readouterr().err
    assert err.count("hearth bench: missions running...") == 1


def test_on_a_terminal_one_progress_line_rewrites_itself(tmp_path):
    import os
    import pty
    leader, follower = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "hearth", "run", "missions/go_to_rest.yaml",
                             "--no-save", "--runs-dir", str(tmp_path)],
                            stdout=follower, stderr=follower, close_fds=True)
    os.close(follower)
    chunks = []
    while True:
        try:
            data = os.read(leader, 65536)
        except OSError:          # the child has closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    os.close(leader)
    assert proc.wait(timeout=120) == 0
    text = b"".join(chunks).decode()
    rewrites = text.count("\r\x1b[K")
    assert rewrites > 10                               # progress updated in place
    assert re.search(r"\r\x1b\[K +[\d.]+s  \.\.\.  NavigateTo drive_near_user: navigating to "
                     r"side_table: \d+%", text)
    shown = [line for line in text.replace("\r\n", "\n").split("\n") if "\r" not in line]
    assert shown[-2].startswith("go_to_rest: succeeded (completed)") and "%" not in shown[-2]


def test_show_finds_a_shipped_mission_by_name_from_any_directory(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["show", "go_to_rest"]) == 0
    assert capsys.readouterr().out.startswith("go_to_rest: ")


def test_serve_announces_its_address_only_once_it_stops_on_ctrl_c(tmp_path):
    """The address line means the server serves and Ctrl-C stops it: even a server started
    with SIGINT ignored (as a child of a process that ignores it) stops on a SIGINT sent
    the moment the line appears."""
    import signal
    proc = subprocess.Popen([sys.executable, "-m", "hearth", "serve", "--port", "0",
                             "--no-save", "--runs-dir", str(tmp_path)],
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        line = next(line for line in proc.stderr if "http" in line)
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert "http://127.0.0.1:" in line
    assert proc.returncode == 0     # stopped by uvicorn's handler, the ignored SIGINT restored
