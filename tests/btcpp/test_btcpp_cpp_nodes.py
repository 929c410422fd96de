"""Hearth's node types in C++ (hearth/executive/cpp/hearth_nodes.hpp, what `hearth export
--nodes-header` writes): a mission using every one of them, exported, compiled into a small
BehaviorTree.CPP program and run there, ends as it ends in Hearth and says the same things.

BehaviorTree.CPP's headers and library are not installable here through pip or apt (the
registry's builds need ROS 2), so the test runs where they are: HEARTH_BTCPP_PREFIX names an
installation prefix (include/behaviortree_cpp/bt_factory.h, lib/libbehaviortree_cpp.so), e.g.
one built from BehaviorTree.CPP 4.8.4's source with cmake; without it the test is skipped."""
from __future__ import annotations

import os
import shutil
import subprocess
from collections import Counter
from pathlib import Path

import pytest

from hearth.executive.btcpp import export_mission, nodes_header
from hearth.executive.executive import Executive
from hearth.executive.testing import Script, Substitution
from hearth.robot.clock import SimClock

HERE = Path(__file__).parent / "cpp"
PREFIX = os.environ.get("HEARTH_BTCPP_PREFIX", "")


def _btcpp() -> Path | None:
    prefix = Path(PREFIX) if PREFIX else None
    if prefix is None or not (prefix / "include/behaviortree_cpp/bt_factory.h").exists():
        return None
    return prefix


needs_btcpp = pytest.mark.skipif(_btcpp() is None or shutil.which("g++") is None,
                                 reason="no BehaviorTree.CPP installation "
                                        "(HEARTH_BTCPP_PREFIX) or no g++")


def test_the_header_is_the_one_export_ships():
    assert "hearth::registerNodes" in nodes_header()
    for node in ("Check", "Guard", "Watch", "ForEach", "StateMachine", "State", "Succeed",
                 "Fail", "SetValue", "Wait"):
        assert f'registerNodeType<{node}>("{node}")' in nodes_header()


@pytest.fixture(scope="module")
def program(tmp_path_factory) -> tuple[Path, Path]:
    """The exported mission and the BT.CPP program compiled with the shipped header."""
    prefix = _btcpp()
    d = tmp_path_factory.mktemp("cpp")
    xml = d / "mission.xml"
    xml.write_text(export_mission(HERE / "nodes_mission.yaml"))
    (d / "hearth_nodes.hpp").write_text(nodes_header())
    exe = d / "run_mission"
    lib = prefix / "lib"
    subprocess.run(["g++", "-std=c++17", "-O0", "-Wall", "-I", str(d), "-I",
                    str(prefix / "include"), str(HERE / "run_mission.cpp"), "-o", str(exe),
                    "-L", str(lib), f"-Wl,-rpath,{lib}", "-lbehaviortree_cpp", "-pthread"],
                   check=True, capture_output=True, text=True, timeout=900)
    return exe, xml


#: mode -> (status, what Say says): slow lets the condition through, stop ends the guard.
RUNS = {"fast": ("SUCCESS", ["kitchen", "hall", "bedroom", "not slow", "watched",
                             "second state"]),
        "slow": ("SUCCESS", ["kitchen", "hall", "bedroom", "watched", "second state"]),
        "stop": ("FAILURE", ["kitchen", "hall", "bedroom", "not slow"])}


@needs_btcpp
@pytest.mark.parametrize("mode", sorted(RUNS))
def test_an_exported_mission_runs_in_btcpp_with_the_cpp_nodes_as_in_hearth(program, mode):
    exe, xml = program
    out = subprocess.run([str(exe), str(xml), f"mode={mode}"], capture_output=True, text=True,
                         timeout=60, check=True).stdout.splitlines()
    said_btcpp = [line[5:] for line in out if line.startswith("say: ")]
    status, said = RUNS[mode]
    assert (out[-1], said_btcpp) == (f"status: {status}", said)

    sub = Substitution([Script("Say")])
    ex = Executive(clock=SimClock(), make_skill=sub, background=False, runs_dir=None)
    handle = ex.submit(str(HERE / "nodes_mission.yaml"), mode=mode)
    ex.run_until_idle(2000)
    said_hearth = [i["text"] for n in sub.made.values() if hasattr(n, "seen_inputs")
                   for i in n.seen_inputs]
    ex.shutdown()
    assert handle.result.outcome == ("succeeded" if status == "SUCCESS" else "failed")
    assert Counter(said_hearth) == Counter(said_btcpp)
