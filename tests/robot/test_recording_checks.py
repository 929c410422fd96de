"""Recordings are checked whole when opened (frames present, complete, of the right kind and
size, inside the folder; every number finite), so a bad one is one line before a mission
starts; version 2 is append-only and survives a kill mid-write; version 1 still reads."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from hearth.cli.main import main
from hearth.robot.errors import RobotError
from hearth.robot.recording import Recording, RecordingWriter, ReplayRobot
from hearth.robot.sim import Frame
from hearth.perception.camera import Intrinsics

K = Intrinsics.kinect(64, 48)


def _frame(i: int) -> Frame:
    rng = np.random.default_rng(i)
    T = np.eye(4)
    T[:3, 3] = (i, 0.0, 1.3)
    from hearth.worldmodel.pose import Pose
    return Frame(color=rng.integers(0, 255, (48, 64, 3), dtype=np.uint8),
                 depth=rng.uniform(0.5, 3.0, (48, 64)).astype(np.float32), intrinsics=K,
                 T_world_camera=T, timestamp=float(i), base_pose=Pose.planar(i, 0.0, 0.0))


@pytest.fixture
def rec(tmp_path) -> Path:
    d = tmp_path / "rec"
    w = RecordingWriter(d, K, info=dict(mission="test"))
    for i in range(3):
        w.add(_frame(i))
    k = w.log_action(dict(time=1.0, action="turn_knob", args={"0": "oven_knob_1"}))
    w.action_done(k, "failed", "oven_knob_1 is stuck")
    w.close()
    return d


def _captures(d: Path) -> list[dict]:
    return [json.loads(line) for line in (d / "captures.jsonl").read_text().splitlines()]


def _rewrite(d: Path, i: int, **fields) -> None:
    caps = _captures(d)
    caps[i].update(fields)
    (d / "captures.jsonl").write_text("".join(json.dumps(c) + "\n" for c in caps))


def test_version_2_reads_back_frames_and_the_action_outcomes(rec):
    r = Recording(rec)
    assert r.version == 2 and len(r) == 3 and r.intrinsics == K
    assert np.array_equal(r.frame(2).color, _frame(2).color)
    assert np.abs(r.frame(2).depth - _frame(2).depth).max() <= 0.0005 + 1e-6
    assert r.actions == [dict(time=1.0, action="turn_knob", args={"0": "oven_knob_1"},
                              status="failed", reason="oven_knob_1 is stuck")]


def test_version_1_still_reads_and_replays(rec):
    r = Recording(rec)
    manifest = json.loads((rec / "manifest.json").read_text())
    manifest.update(version=1, captures=_captures(rec), actions=r.actions)
    (rec / "manifest.json").write_text(json.dumps(manifest))
    (rec / "captures.jsonl").unlink()
    (rec / "actions.jsonl").unlink()
    old = Recording(rec)
    assert old.version == 1 and len(old) == 3 and old.actions == r.actions
    assert np.array_equal(ReplayRobot(old).capture().color, r.frame(0).color)


def _damage(d: Path, case: str) -> str:
    """Break the recording the way ``case`` says; the file the error must name."""
    depth1 = d / "frames" / "0000" / "000001_depth.png"
    manifest = d / "manifest.json"
    if case == "truncated_png":
        data = depth1.read_bytes()
        depth1.write_bytes(data[:len(data) // 2])
        return f"{depth1}: frame 1: truncated PNG"
    if case == "corrupt_png":
        data = bytearray(depth1.read_bytes())
        data[len(data) // 2] ^= 0xFF
        depth1.write_bytes(bytes(data))
        return f"{depth1}: frame 1: corrupt PNG (CRC mismatch in the IDAT chunk)"
    if case == "not_png":
        depth1.write_bytes(b"GIF89a" + bytes(100))
        return f"{depth1}: frame 1: not a PNG file"
    if case == "8_bit_depth":
        import cv2
        cv2.imwrite(str(depth1), np.zeros((48, 64), np.uint8))
        return f"{depth1}: frame 1: depth must be a 16-bit single-channel PNG, this one is 8-bit grey"
    if case == "wrong_size":
        import cv2
        cv2.imwrite(str(depth1), np.zeros((24, 32), np.uint16))
        return f"{depth1}: frame 1: image is 32x24, the intrinsics say 64x48"
    if case in ("nan_depth_scale", "zero_depth_scale", "negative_depth_scale", "fx_0", "inf_cx"):
        m = json.loads(manifest.read_text())
        if case == "fx_0":
            m["intrinsics"]["fx"] = 0
            manifest.write_text(json.dumps(m))
            return f"{manifest}: corrupt manifest: intrinsics.fx must be positive (is 0)"
        if case == "inf_cx":
            m["intrinsics"]["cx"] = math.inf
            manifest.write_text(json.dumps(m))
            return f"{manifest}: corrupt manifest: intrinsics.cx is not finite (inf)"
        m["depth_scale"] = {"nan_depth_scale": math.nan, "zero_depth_scale": 0,
                            "negative_depth_scale": -0.001}[case]
        manifest.write_text(json.dumps(m))            # json writes NaN as NaN
        return {"nan_depth_scale": f"{manifest}: corrupt manifest: depth_scale is not finite (nan)",
                "zero_depth_scale": f"{manifest}: corrupt manifest: depth_scale must be positive (is 0)",
                "negative_depth_scale": f"{manifest}: corrupt manifest: depth_scale must be positive (is -0.001)"}[case]
    caps = d / "captures.jsonl"
    if case == "nan_pose":
        _rewrite(d, 2, base_pose=dict(x=math.nan, y=0.0, yaw=0.0))
        return f"{caps}:3: capture 2: base_pose.x is not finite (nan)"
    if case == "not_rigid":
        _rewrite(d, 1, T_world_camera=(2 * np.eye(4)).tolist())
        return f"{caps}:2: capture 1: T_world_camera is not a rigid transform"
    if case == "infinite_number":
        _rewrite(d, 0, pan=1e400)                      # json reads it as inf
        return f"{caps}:1: capture 0: pan is not finite (inf)"
    if case == "absolute_path":
        _rewrite(d, 1, depth="/etc/passwd")
        return f"{d / '/etc/passwd'}: frame 1: frame path '/etc/passwd' is absolute"
    if case == "escaping_path":
        _rewrite(d, 1, depth="../../../../proc/self/environ")
        return "frame 1: frame path '../../../../proc/self/environ' leaves the recording's folder"
    if case == "symlink_out":
        os.symlink("/dev/zero", d / "frames" / "zero.png")
        _rewrite(d, 1, depth="frames/zero.png")
        return "frame 1: frame path 'frames/zero.png' leaves the recording's folder"
    if case == "directory":
        _rewrite(d, 1, depth="frames")
        return f"{d / 'frames'}: frame 1: frame path 'frames' is not a regular file"
    if case == "corrupt_line":
        with open(caps, "a") as f:
            f.write("{not json\n{}\n")
        return f"{caps}:4: corrupt line"
    if case == "capture_not_object":
        with open(caps, "a") as f:
            f.write("[1, 2]\n")
        return f"{caps}:4: capture 3: a capture must be a JSON object"
    raise AssertionError(case)


CASES = ["truncated_png", "corrupt_png", "not_png", "8_bit_depth", "wrong_size",
         "nan_depth_scale", "zero_depth_scale", "negative_depth_scale", "fx_0", "inf_cx",
         "nan_pose", "not_rigid", "infinite_number", "absolute_path", "escaping_path", "symlink_out",
         "directory", "corrupt_line", "capture_not_object"]


@pytest.mark.parametrize("case", CASES)
def test_a_bad_recording_is_refused_whole_when_opened_in_one_line(case, rec):
    expected = _damage(rec, case)
    with pytest.raises(RobotError) as err:
        Recording(rec)
    msg = str(err.value)
    assert "\n" not in msg and expected in msg, msg


def test_hearth_run_on_a_bad_recording_stops_before_the_mission_with_exit_2(rec, tmp_path, capsys):
    _damage(rec, "truncated_png")
    status = main(["run", "missions/turn_off_oven.yaml", "--recording", str(rec),
                   "--runs-dir", str(tmp_path / "runs")])
    cap = capsys.readouterr()
    assert status == 2 and cap.out == "" and cap.err.count("\n") == 1
    assert cap.err.startswith(f"{rec / 'frames' / '0000' / '000001_depth.png'}: frame 1: truncated PNG")
    assert not (tmp_path / "runs").exists()                # no run was started


KILLED = textwrap.dedent("""
    import os, signal, sys
    import numpy as np
    from hearth.robot.recording import RecordingWriter
    from hearth.robot.sim import Frame
    from hearth.perception.camera import Intrinsics
    from hearth.worldmodel.pose import Pose
    K = Intrinsics.kinect(64, 48)
    f = Frame(color=np.zeros((48, 64, 3), np.uint8), depth=np.ones((48, 64), np.float32),
              intrinsics=K, T_world_camera=np.eye(4), base_pose=Pose.planar(0, 0, 0))
    w = RecordingWriter(sys.argv[1], K)
    w.add(f)
    w.add(f)
    if sys.argv[2] == "line":            # killed halfway through writing the third line
        w._captures.write('{"index": 2, "color": "frames/0000/000002_color.png", "dep')
        w._captures.flush()
    else:                                # killed while the header's temporary file is written
        os.replace = lambda *a: os.kill(os.getpid(), signal.SIGKILL)
        w.set_start_pose(Pose.planar(1, 2, 3))
    os.kill(os.getpid(), signal.SIGKILL)
""")


@pytest.mark.parametrize("where", ["line", "header"])
def test_a_recording_killed_mid_write_stays_readable_and_leaves_no_temporary_file(where, tmp_path):
    d = tmp_path / "rec"
    p = subprocess.run([sys.executable, "-c", KILLED, str(d), where], capture_output=True)
    assert p.returncode == -9
    r = Recording(d)
    assert len(r) == 2 and r.start_pose is None
    if where == "header":
        assert list(d.glob("*.tmp"))                    # what the kill left ...
        RecordingWriter(tmp_path / "rec", K)            # ... the next writer there removes
        assert not list(d.glob("*.tmp"))
    else:
        assert not list(d.glob("*.tmp"))


# -- issue 44: files of a recording a hostile tool could write ------------------------------

def _manifest(d: Path, **fields) -> Path:
    m = json.loads((d / "manifest.json").read_text())
    m.update(fields)
    (d / "manifest.json").write_text(json.dumps(m))
    return d / "manifest.json"


def _refused(d: Path) -> str:
    with pytest.raises(RobotError) as err:
        Recording(d)
    message = str(err.value)
    assert "\n" not in message and len(message) < 500
    return message


@pytest.mark.parametrize("where", ["manifest", "captures", "actions"])
def test_an_integer_of_5000_digits_is_one_line_naming_the_file(rec, where):
    big = "9" * 5000
    if where == "manifest":
        text = (rec / "manifest.json").read_text().replace('"version": 2', f'"version": {big}')
        (rec / "manifest.json").write_text(text)
        expected = f"{rec / 'manifest.json'}:3: corrupt manifest: an integer of 5000 digits"
    else:
        path = rec / f"{where}.jsonl"
        lines = path.read_text().splitlines()
        lines[0] = lines[0].replace('"timestamp": 0.0', f'"timestamp": {big}') \
            .replace('"i": 0', f'"i": {big}')
        path.write_text("\n".join(lines) + "\n")
        expected = f"{path}:1: corrupt line: an integer of 5000 digits"
    assert _refused(rec).startswith(expected)


def test_a_frame_path_with_a_nul_byte_is_refused(rec):
    _rewrite(rec, 1, color="frames/0000/000001_color.png\x00.txt")
    assert "frame 1: frame path 'frames/0000/000001_color.png\\x00.txt' holds a NUL byte" \
        in _refused(rec)


@pytest.mark.parametrize("name", ["captures.jsonl", "actions.jsonl", "manifest.json"])
@pytest.mark.parametrize("kind", ["fifo", "dev_zero", "sparse_3GB", "link_out"])
def test_the_recordings_own_files_are_bounded_regular_files_inside_its_folder(rec, tmp_path,
                                                                               name, kind):
    path = rec / name
    path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
        words = "is not a regular file"
    elif kind == "dev_zero":
        path.symlink_to("/dev/zero")
        words = "leaves the recording's folder"
    elif kind == "link_out":
        (tmp_path / "elsewhere.json").write_text("{}\n")
        path.symlink_to(tmp_path / "elsewhere.json")
        words = "leaves the recording's folder"
    else:
        with open(path, "wb") as f:         # sparse: no disk used
            f.truncate(3 << 30)
        words = "more than the"
    message = _refused(rec)
    assert message.startswith(f"{path}: ") and words in message


@pytest.mark.parametrize("fields, words", [
    (dict(depth_scale=1e300), "depth_scale 1e+300 is not between 1e-05 and 0.01"),
    (dict(depth_scale=1e-60), "depth_scale 1e-60 is not between 1e-05 and 0.01"),
    (dict(start_pose=dict(x=1e300, y=0.0, yaw=0.0)), "start_pose.x is beyond +-10000"),
    (dict(start_pose=dict(x=0.0, y=0.0, yaw=-1e300)), "start_pose.yaw is beyond +-10000"),
    (dict(intrinsics=dict(fx=500.0, fy=500.0, cx=8000.0, cy=8000.0, width=16384,
                          height=16384)), "intrinsics.width must be a whole number of pixels up "
                                          "to 8192"),
    (dict(intrinsics=dict(fx=500.0, fy=500.0, cx=4000.0, cy=4000.0, width=8000,
                          height=8000)), "8000x8000 is more than the 16777216 pixels"),
])
def test_absurd_header_numbers_are_refused(rec, fields, words):
    path = _manifest(rec, **fields)
    message = _refused(rec)
    assert message.startswith(f"{path}: corrupt manifest: ") and words in message


def test_an_rgba_colour_frame_is_refused(rec):
    import cv2
    color = rec / "frames" / "0000" / "000002_color.png"
    cv2.imwrite(str(color), np.zeros((48, 64, 4), np.uint8))
    assert _refused(rec) == (f"{color}: frame 2: colour must be an 8-bit 3-channel (RGB) PNG, "
                             "this one is 8-bit RGBA")


def test_a_frame_named_by_twenty_thousand_captures_is_checked_once(rec, monkeypatch):
    import hearth.robot.recording as recording
    line = (rec / "captures.jsonl").read_text().splitlines()[0]
    (rec / "captures.jsonl").write_text((line + "\n") * 20_000)
    calls = []
    real = recording.check_depth_png
    monkeypatch.setattr(recording, "check_depth_png", lambda data: calls.append(1) or real(data))
    r = Recording(rec)
    assert len(r) == 20_000 and len(calls) == 1


def test_a_rotation_of_huge_numbers_is_not_rigid_and_prints_no_warning(rec):
    import warnings
    T = np.eye(4)
    T[0, 0] = T[1, 1] = 1e308
    _rewrite(rec, 1, T_world_camera=T.tolist())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        message = _refused(rec)
    assert message.endswith("capture 1: T_world_camera is not a rigid transform")
