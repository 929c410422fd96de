"""A wheel of Hearth installs non-editable into a fresh virtual environment next to Robot
Framework (whose import name is ``robot``), and the shipped demo home and missions work from
another directory.

To stay quick the fresh environment reaches the dependencies already installed here through a
.pth file (the wheel goes in with --no-deps); Robot Framework comes from the package index and
the test is skipped, saying so, only when the index cannot be reached.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SKIP_DIRS = {".git", ".venv", "build", "runs", "out", ".pytest_cache", ".hypothesis",
             "__pycache__", ".models"}


def pip(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", *args],
                          capture_output=True, text=True, cwd=cwd)


def source_copy(dest: Path) -> Path:
    """The checkout without its virtual environment and build outputs (pip builds in place)."""
    def ignore(directory, names):
        return [n for n in names if n in SKIP_DIRS or n.endswith(".egg-info")]
    shutil.copytree(ROOT, dest, ignore=ignore)
    return dest


pytestmark = pytest.mark.timeout(900)    # a wheel build and a fresh venv on a busy machine


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(python, hearth script, environment) of a fresh venv with the wheel and robotframework."""
    tmp = tmp_path_factory.mktemp("wheel")
    got = pip("download", "--no-deps", "--only-binary", ":all:", "--retries", "1", "--timeout", "30",
              "-d", str(tmp / "dl"), "robotframework", "perception")   # fail fast when offline
    if got.returncode != 0:
        last = (got.stderr.strip().splitlines() or ["no output"])[-1]
        pytest.skip(f"the package index cannot be reached for robotframework and perception: "
                    f"{last}")
    built = pip("wheel", "--no-deps", "-q", "-w", str(tmp / "dist"), str(source_copy(tmp / "src")))
    assert built.returncode == 0, built.stderr
    wheel = next((tmp / "dist").glob("hearth-*.whl"))

    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    purelib = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                  capture_output=True, text=True, check=True).stdout.strip())
    # The dependencies already installed here, after the fresh venv's own packages on sys.path
    # (a path in a .pth file is appended, and .pth files inside it are not run: the editable
    # install of this checkout stays out).
    (purelib / "hearth-test-deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    # perception: the perceptual-hashing library, whose import name Hearth used to install too
    for what in ([str(wheel)], [str(next((tmp / "dl").glob("robotframework-*.whl")))],
                 [str(next((tmp / "dl").glob("perception-*.whl")))]):
        done = pip("--python", str(python), "install", "--no-deps", "-q", *what)
        assert done.returncode == 0, done.stderr
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return python, venv / "bin" / "hearth", env, tmp / "elsewhere"


def run(installed, *args) -> subprocess.CompletedProcess:
    python, hearth, env, cwd = installed
    cwd.mkdir(exist_ok=True)
    return subprocess.run([str(hearth), *args], capture_output=True, text=True, cwd=cwd, env=env)


def test_hearth_and_robot_framework_install_side_by_side(installed):
    python, _, env, cwd = installed
    cwd.mkdir(exist_ok=True)
    code = ("import robot, robot.version, hearth, hearth.robot, hearth.executive, hearth.worldmodel\n"
            "print(robot.__file__); print(robot.version.VERSION)\n"
            "print(hearth.__file__); print(hearth.executive.__file__)\n"
            "print(hearth.missions_dir()); print(hearth.demo_world_path())\n")
    out = subprocess.run([str(python), "-c", code], capture_output=True, text=True, cwd=cwd, env=env)
    assert out.returncode == 0, out.stderr
    robot_file, version, hearth_file, executive_file, missions, world = out.stdout.split("\n")[:6]
    venv = str(python.parent.parent)
    assert robot_file.startswith(venv) and version
    for path in (hearth_file, executive_file, missions, world):
        assert path.startswith(venv) and "site-packages" in path, path    # not the checkout
    assert Path(missions, "go_to_rest.yaml").is_file() and Path(world).is_file()


def test_hearth_installs_one_top_level_import_name(installed):
    python, _, env, cwd = installed
    cwd.mkdir(exist_ok=True)
    top = subprocess.run([str(python), "-c", "import importlib.metadata as m; "
                          "print(m.distribution('hearth').read_text('top_level.txt') or '')"],
                         capture_output=True, text=True, env=env, cwd=cwd)
    files = subprocess.run([str(python), "-c", "import importlib.metadata as m; print(sorted({"
                            "f.parts[0] for f in m.distribution('hearth').files if f.parts[0] != '..'}))"],
                           capture_output=True, text=True, env=env, cwd=cwd, check=True).stdout
    assert eval(files) == ["hearth", f"hearth-{hearth_version()}.dist-info"], files
    assert top.stdout.split() in ([], ["hearth"]), top.stdout
    for name in ("executive", "skills", "worldmodel"):
        gone = subprocess.run([str(python), "-c", f"import {name}"], capture_output=True,
                              text=True, env=env, cwd=cwd)
        assert "ModuleNotFoundError" in gone.stderr, (name, gone.stderr)
    # `perception` is now the perceptual-hashing library's, installed beside Hearth
    theirs = subprocess.run([str(python), "-c", "import importlib.util as u; "
                             "print(u.find_spec('perception').origin)"],
                            capture_output=True, text=True, env=env, cwd=cwd, check=True)
    assert "hearth" not in theirs.stdout, theirs.stdout


def hearth_version() -> str:
    from hearth import __version__
    return __version__


def test_the_installed_cli_shows_help_validates_and_runs_from_another_directory(installed):
    python, _, env, cwd = installed
    shipped = subprocess.run([str(python), "-c", "import hearth; print(hearth.missions_dir()); "
                              "print(hearth.demo_world_path())"], capture_output=True, text=True,
                             env=env, check=True).stdout.split()
    missions, world = Path(shipped[0]), shipped[1]
    helped = run(installed, "demo", "--help")
    assert helped.returncode == 0 and "usage: hearth demo" in helped.stdout
    files = [world] + sorted(str(p) for p in missions.rglob("*.yaml"))
    assert len(files) > 5
    checked = run(installed, "validate", *files)
    assert (checked.returncode, checked.stderr) == (0, "")
    ran = run(installed, "run", "missions/go_to_rest.yaml", "--quiet")
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.startswith("go_to_rest: succeeded") and ran.stderr == ""
    assert list((cwd / "runs").glob("*-go_to_rest-*.jsonl"))     # the log lands where we are


def test_the_installed_export_writes_the_cpp_nodes_header(installed):
    python, _, env, cwd = installed
    mission = subprocess.run([str(python), "-c", "import hearth; print(hearth.missions_dir())"],
                             capture_output=True, text=True, env=env, check=True).stdout.strip()
    done = run(installed, "export", f"{mission}/go_to_rest.yaml", "-o", "rest.xml",
               "--nodes-header", "hearth_nodes.hpp")
    assert done.returncode == 0, done.stderr
    assert "hearth::registerNodes" in (cwd / "hearth_nodes.hpp").read_text()
