"""The five error families share one base (hearth.util.errors.HearthError) and print the same
one-line messages they printed before it existed."""
from __future__ import annotations

import pytest

from hearth.cli.main import main
from hearth.executive.errors import MissionError, MissionValidationError
from hearth.util.errors import HearthError
from hearth.robot.errors import RobotError
from hearth.perception.errors import PerceptionError
from hearth.skills.errors import SkillError
from hearth.worldmodel.errors import UnknownNode, WorldError, WorldValidationError


@pytest.mark.parametrize("family", [WorldError, PerceptionError, MissionError, RobotError,
                                    SkillError, UnknownNode])
def test_every_family_is_a_hearth_error_with_its_message(family):
    err = family("no such thing")
    assert isinstance(err, HearthError)
    assert str(err) == "no such thing"
    assert err.message == "no such thing"


@pytest.mark.parametrize("family", [WorldError, PerceptionError, MissionError])
def test_a_file_problem_prints_path_and_line_and_line_zero_when_unknown(family):
    assert str(family("bad pose", file="home.xml", line=12)) == "home.xml:12: bad pose"
    assert str(family("bad pose", file="home.xml")) == "home.xml:0: bad pose"
    assert str(family("bad pose", file="home.xml", line=0)) == "home.xml:0: bad pose"


def test_a_recording_file_without_a_line_prints_the_path_alone():
    assert str(RobotError("frame 3 is missing", file="rec/0003.png")) == "rec/0003.png: frame 3 is missing"
    assert str(RobotError("corrupt manifest", file="rec/manifest.json", line=4)) == \
        "rec/manifest.json:4: corrupt manifest"


@pytest.mark.parametrize("family", [WorldError, PerceptionError, RobotError, SkillError])
def test_a_map_problem_names_the_node(family):
    assert str(family("is gone", node="blue_cup")) == "node blue_cup: is gone"


def test_a_file_wins_over_a_node():
    assert str(WorldError("x", file="a.xml", line=2, node="n")) == "a.xml:2: x"


def test_a_mission_parameter_problem_names_the_parameter():
    assert str(MissionError("not a number", param="speed")) == "parameter speed: not a number"
    assert str(MissionError("bad", file="m.yaml", line=3, param="speed")) == "m.yaml:3: bad"


def test_validation_errors_print_one_line_per_problem():
    world = WorldValidationError([WorldError("a", file="w.xml", line=1), WorldError("b", node="n")])
    assert str(world) == "w.xml:1: a\nnode n: b"
    mission = MissionValidationError([MissionError("a", file="m.yaml", line=2),
                                      MissionError("b", param="p")])
    assert str(mission) == "m.yaml:2: a\nparameter p: b"


def test_the_cli_turns_a_skill_error_into_one_line_and_status_2(monkeypatch, capsys):
    import hearth.cli.commands.validate as validate

    def broken(path):
        raise SkillError("not a pose: 'x'", node="kitchen_table")
    monkeypatch.setattr(validate, "problems_in", broken)
    assert main(["validate", "whatever.xml"]) == 2
    assert capsys.readouterr().err == "node kitchen_table: not a pose: 'x'\n"


def test_a_file_with_many_problems_prints_the_first_fifty_and_counts_the_rest():
    from hearth.util.errors import MOST_PROBLEMS_PRINTED

    problems = [WorldError(f"problem {i}", file="w.xml", line=i + 1) for i in range(120)]
    lines = str(WorldValidationError(problems)).splitlines()
    assert len(lines) == MOST_PROBLEMS_PRINTED + 1 == 51
    assert lines[0] == "w.xml:1: problem 0" and lines[49] == "w.xml:50: problem 49"
    assert lines[-1] == "... and 70 more problems (120 in all)"
    mission = MissionValidationError([MissionError(f"p{i}", file="m.yaml", line=i) for i in range(51)])
    assert str(mission).splitlines()[-1] == "... and 1 more problems (51 in all)"
