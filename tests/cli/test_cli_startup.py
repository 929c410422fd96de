"""`hearth --help` and `hearth validate WORLD` load only what they need (the start-up time
itself is measured by `hearth bench cli`)."""
from __future__ import annotations

import json
import subprocess
import sys

import hearth

HEAVY = ("numpy", "scipy", "py_trees", "open3d", "cv2", "sklearn", "jsonschema", "fastapi",
         "transitions", "yaml", "lxml")


def modules_after(argv: list[str]) -> set[str]:
    code = ("import contextlib, io, json, sys\n"
            "from hearth.cli.main import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    try:\n"
            f"        status = main({argv!r})\n"
            "    except SystemExit as e:\n"
            "        status = e.code\n"
            "print(json.dumps([status, sorted(sys.modules)]))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    status, names = json.loads(out.stdout.strip().splitlines()[-1])
    assert status in (0, None), out.stderr
    return {n.split(".")[0] for n in names}


def test_help_lists_every_command_without_loading_any_third_party_package():
    loaded = modules_after(["--help"])
    assert not loaded & set(HEAVY), sorted(loaded & set(HEAVY))
    for name in ("demo", "run", "validate", "bench", "serve"):
        assert modules_after([name, "--help"]).isdisjoint(HEAVY)


def test_validate_world_loads_neither_scipy_nor_the_mission_machinery():
    loaded = modules_after(["validate", str(hearth.demo_world_path())])
    assert "lxml" in loaded
    assert not loaded & {"scipy", "py_trees", "open3d", "cv2", "sklearn", "jsonschema", "yaml"}


def test_worldmodel_still_re_exports_its_names():
    import hearth.worldmodel
    from hearth.worldmodel import Pose, World, load_world
    assert World.__module__ == "hearth.worldmodel.world" and Pose.__module__ == "hearth.worldmodel.pose"
    assert callable(load_world)
    assert set(hearth.worldmodel.__all__) <= set(dir(hearth.worldmodel))
    assert hearth.worldmodel.io.load_world is load_world


def test_hearth_robot_still_re_exports_the_adapter_protocol():
    from hearth import robot
    from hearth.robot import RobotAdapter, wait
    from hearth.robot.adapter import RobotAdapter as direct
    assert RobotAdapter is direct and callable(wait) and callable(robot.create_adapter)
