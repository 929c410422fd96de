"""Helpers for executive tests: write missions to tmp files, run them on a SimClock."""
import textwrap

import pytest

from hearth.executive.executive import Executive
from hearth.executive.testing import Script, ScriptedSkill, Substitution, test_skills
from hearth.robot.clock import SimClock


@pytest.fixture
def mission_file(tmp_path):
    def write(text, name="m.yaml"):
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return str(path)
    return write


@pytest.fixture
def journal():
    ScriptedSkill.journal = []
    yield ScriptedSkill.journal
    ScriptedSkill.journal = None


@pytest.fixture
def make_executive(tmp_path):
    made = []

    def make(scripts=(), robot=None, world=None, **kw):
        kw.setdefault("runs_dir", str(tmp_path / "runs"))
        kw.setdefault("skills", test_skills())
        ex = Executive(world=world, robot=robot, clock=SimClock(), tick_hz=10,
                       make_skill=Substitution(list(scripts), None),
                       background=kw.pop("background", False), **kw)
        made.append(ex)
        return ex
    yield make
    for ex in made:
        ex.shutdown()


S = Script
