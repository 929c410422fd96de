"""`hearth run` / `hearth step` end to end: the real NavigateTo and Say skills, the demo home,
and a fake robot adapter standing in for robot.create_adapter."""
import re

import pytest

from hearth import robot
from hearth.cli.main import main


class FakeAction:
    def __init__(self, clock, seconds):
        self.clock, self.end, self.cancelled = clock, clock.now() + seconds, False
        self.progress = 0.0
        self.reason = ""

    def status(self):
        if self.cancelled:
            return "cancelled"
        return "succeeded" if self.clock.now() >= self.end - 1e-9 else "running"

    def cancel(self):
        self.cancelled = True


class FakeAdapter:
    def __init__(self, clock):
        self.clock, self.goals, self.said, self.stops = clock, [], [], 0

    def navigate_to(self, pose):
        self.goals.append(pose)
        return FakeAction(self.clock, 1.0)

    def say(self, text):
        self.said.append(text)

    def stop(self):
        self.stops += 1


@pytest.fixture
def adapters(monkeypatch):
    made = []

    def create_adapter(world=None, scenario=None, recording=None, clock=None):
        made.append(FakeAdapter(clock))
        return made[-1]

    monkeypatch.setattr(robot, "create_adapter", create_adapter, raising=False)
    return made


def test_hearth_run_go_to_rest_drives_and_speaks(adapters, tmp_path, capsys):
    status = main(["run", "missions/go_to_rest.yaml", "--runs-dir", str(tmp_path)])
    out = capsys.readouterr().out
    assert status == 0, out
    assert "go_to_rest: succeeded (completed)" in out
    (adapter,) = adapters
    assert len(adapter.goals) == 1 and adapter.said == ["I am resting nearby. Call me if you need me."]
    assert list(tmp_path.glob("*.jsonl"))


def test_hearth_step_non_interactive_prints_tree_and_blackboard(adapters, tmp_path, capsys):
    status = main(["step", "missions/go_to_rest.yaml", "--param", "presence=away",
                   "--ticks", "3", "--runs-dir", str(tmp_path)])
    out = capsys.readouterr().out
    assert status == 0
    assert "*         |-- NavigateTo drive_out_of_the_way(target={away_target})" in out
    assert re.search(r"^\$presence +=  'away'$".replace("=  ", "= "), out, re.M)
    assert adapters[0].stops == 1          # cancelled at the end of stepping: robot stopped


def test_run_without_a_robot_adapter_is_one_clear_line(monkeypatch, capsys):
    monkeypatch.delattr(robot, "create_adapter", raising=False)
    assert main(["run", "missions/go_to_rest.yaml"]) == 2
    assert capsys.readouterr().err.strip() == \
        "no robot adapter: robot.create_adapter() does not exist yet"


def test_hearth_step_interactive_commands(adapters, tmp_path, capsys, monkeypatch):
    commands = iter(["u drive_near_user", "t 2", "p", "b", "u nothing_like_it", "x", "q"])
    monkeypatch.setattr("builtins.input", lambda prompt="": next(commands))
    status = main(["step", "missions/go_to_rest.yaml", "--runs-dir", str(tmp_path)])
    out = capsys.readouterr().out
    assert status == 1                                   # quit: the mission was cancelled
    assert "* `-- sequence choose_rest_place (memory)" in out
    assert re.search(r"^near_target +=  'side_table'$".replace("=  ", "= "), out, re.M)  # RestPlace's
    assert "no node named 'nothing_like_it'" in out
    assert "t [N]: tick N times" in out                  # help after the unknown 'x'
    assert "go_to_rest: cancelled (quit from hearth step)" in out
