"""The hand-made fuzz cases of issues 19 and 44, each with the outcome it must get and, for
issue 44's, its class (``fixed_cases``)."""
from __future__ import annotations

import copy
import json
import re

from hearth.benchmarks.fuzz_case import Case
from hearth.benchmarks.fuzz_checks import _has_ros
from hearth.benchmarks.fuzz_generate import (
    _demo_world, HOSTILE_MESHES, _missions, _recording_files, WORLD_NEIGHBOURS,
)


# ---------------------------------------------------------------------------------------------
# Fixed cases (issue 19's hand-made ones)

def fixed_cases() -> list[Case]:
    import re
    world = _demo_world().decode()
    missions = _missions()
    out: list[Case] = []

    def w(name, text, expect="refused", klass=""):
        out.append(Case("world", name, {**WORLD_NEIGHBOURS, "world.xml": text.encode()},
                        "world.xml", expect, klass))

    def first(pattern, repl, text=world):
        new, n = re.subn(pattern, repl, text, count=1)
        assert n == 1, pattern
        return new

    w("demo_world", world, "accepted")
    w("nan_pose", first(r'<pose x="3" y="2.2"/>', '<pose x="NaN" y="2.2"/>'))
    w("inf_parking", first(r'(<position id="[^"]*" x=")[^"]*"', r'\1INF"'))
    w("nan_parking", first(r'(<position id="[^"]*" x="[^"]*" y=")[^"]*"', r'\1NaN"'))
    w("nan_joint_limit", first(r'upper="[^"]*"', 'upper="NaN"'))
    w("inf_joint_state", first(r'(<joint [^>]*)state="[^"]*"', r'\1state="INF"'))
    w("nan_knob_angle", first(r'(<knob [^>]*)angle="[^"]*"', r'\1angle="NaN"'))
    w("coordinate_1e308", first(r'<pose x="3" y="2.2"/>', '<pose x="1e308" y="2.2"/>'))
    w("size_1e999", first(r'size="1.2 0.8 0.03"', 'size="1.2 1e999 0.03"'))
    w("knob_radius_zero", first(r'(<knob [^>]*)radius="[^"]*"', r'\1radius="0"'))
    w("handle_radius_zero", first(r'(<handle [^>]*)radius="[^"]*"', r'\1radius="0"'))
    for label, path in (("mesh_etc_passwd", "../../etc/passwd"), ("mesh_absolute", "/etc/passwd"),
                        ("mesh_dev_zero", "/dev/zero"), ("mesh_proc", "/proc/self/environ"),
                        ("mesh_directory", "emptydir"), ("mesh_fifo", "fifo.ply"),
                        ("mesh_symlink_out", "escape.ply"), ("mesh_dir_symlink_out", "etc/passwd")):
        w(label, first(r'(<model>)', rf'\1<mesh file="{path}" color="0.5 0.5 0.5"/>'))
    w("mesh_inside", first(r'(<model>)', r'\1<mesh file="sub/inner.ply" color="0.5 0.5 0.5"/>'),
      "accepted")
    w("pointcloud_proc", first(r'(<room id="kitchen")', r'\1 pointcloud="../../../proc/self/environ"'))
    w("attribute_10MB", first(r'(<(?:LargeObject|LargeArticulatedObject) [^>]*)name="[^"]*"',
                              r'\1name="' + "x" * 10_000_000 + '"'))
    w("rooms_20000", world.replace("</apartment>", "".join(
        f'<room id="fr{i}" name="r"/>' for i in range(20000)) + "</apartment>"))
    w("part_nesting_100", first(r"(</LargeArticulatedObject>)", "".join(
        f'<part id="fp{i}" type="door"><joint type="fixed"/>' for i in range(100))
        + "</part>" * 100 + r"\1"))
    w("billion_laughs", '<?xml version="1.0"?>\n<!DOCTYPE l [<!ENTITY a "aaaaaaaaaa">'
      '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>\n<apartment id="x" version="1">'
      '<room id="r" name="&b;"/></apartment>\n')

    def m(name, text, expect="refused", extra=None, klass=""):
        files = {**missions, "case.yaml": text.encode(), **(extra or {})}
        out.append(Case("mission", name, files, "case.yaml", expect, klass))

    bomb = ("a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n"
            + "".join(f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n"
                      for p, c in zip("abcdefgh", "bcdefghi")))
    indent = lambda text, n: "".join(" " * n + line + "\n" for line in text.splitlines())
    m("alias_bomb_blackboard", "name: bomb\nblackboard:\n" + indent(bomb, 2)
      + "tree:\n  succeed: ok\n")
    m("alias_bomb_parameter_default", "name: bomb\nparameters:\n  p:\n    type: any\n"
      "    default:\n" + indent(bomb, 6) + "tree:\n  succeed: ok\n")
    m("alias_bomb_skill_input", "name: bomb\ntree:\n  skill: Say\n  inputs:\n    text:\n"
      + indent(bomb, 6))
    m("alias_recursive", "name: r\nblackboard: {x: &a [*a]}\ntree:\n  succeed: ok\n")
    m("wide_10000", "name: wide\ntree:\n  sequence:\n"
      + "    - skill: Say\n      inputs: {text: hi}\n" * 10_000, "accepted")
    m("deep_3000_inverters", "name: deep\ntree: " + "{inverter: " * 3000 + "{succeed: ok}"
      + "}" * 3000 + "\n")
    m("deep_yaml_flow", "name: deep\ntree: " + "[" * 100_000 + "\n")
    m("retry_1e26", "name: r\ntree:\n  retry: {succeed: ok}\n  times: 100000000000000000000000000\n")
    m("retry_1e6", "name: r\ntree:\n  retry: {succeed: ok}\n  times: 1000000\n")
    m("timeout_nan", "name: r\ntree:\n  timeout: {succeed: ok}\n  seconds: .nan\n")
    m("timeout_inf", "name: r\ntree:\n  timeout: {succeed: ok}\n  seconds: .inf\n")
    m("timeout_1e9", "name: r\ntree:\n  timeout: {succeed: ok}\n  seconds: 1000000000\n")
    m("nan_input", "name: r\ntree:\n  skill: NavigateTo\n  inputs: {target: {x: .nan, y: 0}}\n")
    m("huge_integer", "name: r\nblackboard: {n: " + "9" * 5000 + "}\ntree:\n  succeed: ok\n")
    m("python_tag", "name: r\nblackboard: {n: !!python/object/apply:os.system ['true']}\n"
      "tree:\n  succeed: ok\n")
    for label, target in (("include_etc_passwd", "/etc/passwd#x"),
                          ("include_proc_environ", "../../../../proc/self/environ#x"),
                          ("include_dev_zero", "/dev/zero#x"),
                          ("include_directory", "subtrees/#x"),
                          ("include_escape", "../../../../etc/passwd")):
        m(label, f"name: r\ntree:\n  include: '{target}'\n")
    m("include_inside", "name: r\nblackboard: {notes: []}\ntree:\n"
      "  include: subtrees/search.yaml#note\n  params: {text: hi, about: x, notes: '{notes}'}\n",
      "accepted")
    inc_bomb = "name: r\ntree:\n  include: s0\nsubtrees:\n" + "".join(
        f"  s{i}:\n    tree:\n      sequence:\n        - include: s{i + 1}\n"
        f"        - include: s{i + 1}\n" for i in range(24)) + "  s24:\n    tree: {succeed: ok}\n"
    m("include_bomb", inc_bomb)

    rec = _recording_files()
    man = json.loads(rec["rec/manifest.json"])

    def r(name, manifest=None, files=None, expect="refused"):
        f = {**rec, **(files or {})}
        if manifest is not None:
            f["rec/manifest.json"] = json.dumps(manifest).encode()
        for k, v in list(f.items()):
            if v is None:
                del f[k]
        out.append(Case("recording", name, f, "rec", expect))

    def with_(path, value):
        d = copy.deepcopy(man)
        cur = d
        for k in path[:-1]:
            cur = cur[k]
        cur[path[-1]] = value
        return d

    import cv2
    import numpy as np
    r("valid", expect="accepted")
    r("missing_png", files={"rec/frames/000001_depth.png": None})
    r("truncated_png", files={"rec/frames/000001_color.png": rec["rec/frames/000001_color.png"][:40]})
    r("corrupt_png", files={"rec/frames/000000_depth.png": b"\x89PNG\r\n\x1a\n" + b"\x00" * 64})
    r("depth_8_bit", files={"rec/frames/000000_depth.png":
                            cv2.imencode(".png", np.zeros((24, 32), np.uint8))[1].tobytes()})
    r("wrong_size", files={"rec/frames/000001_color.png":
                           cv2.imencode(".png", np.zeros((10, 7, 3), np.uint8))[1].tobytes()})
    r("depth_scale_nan", with_(["depth_scale"], float("nan")))
    r("depth_scale_zero", with_(["depth_scale"], 0))
    r("depth_scale_negative", with_(["depth_scale"], -0.001))
    r("pose_nan", with_(["captures", 0, "base_pose", "x"], float("nan")))
    r("fx_zero", with_(["intrinsics", "fx"], 0))
    r("frame_etc_passwd", with_(["captures", 0, "color"], "/etc/passwd"))
    r("frame_escape", with_(["captures", 0, "depth"], "../../../../etc/passwd"))
    out.extend(_issue_44_cases(world, first, w, m))
    return out


def _issue_44_cases(world: str, first, w, m) -> list[Case]:
    """Issue 44's hand-made cases, each tagged with its class (CLASSES)."""
    import cv2
    import numpy as np
    out: list[Case] = []

    def mesh(path):
        return first(r'(<model>)', rf'\1<mesh file="{path}" color="0.5 0.5 0.5"/>')

    for name in HOSTILE_MESHES:
        w(f"mesh_{name}", mesh(name), klass="fifo" if "fifo" in name else "mesh-content")
    w("mesh_obj_with_material_inside", mesh("ok.obj"), "accepted", klass="mesh-content")
    w("pointcloud_nan", first(r'(<room id="kitchen")', r'\1 pointcloud="nan.ply"'),
      klass="mesh-content")
    w("attributes_100000", first(r'(<room id="kitchen")', r'\1 ' + " ".join(
        f'a{i}="1"' for i in range(100_000))), klass="size")
    w("duplicate_surface_id", first(r'(<surface id="top")', r'<surface id="top" sizeX="1" '
                                    r'sizeY="1"><pose z="0.5"/></surface>\1'), klass="structure")
    # an object and a place of the base world, whatever it is
    obj = re.search(r'<SmallObject id="([^"]+)"', world).group(1)
    place = re.search(r'<Large(?:Articulated)?Object id="([^"]+)"', world).group(1)
    stats = lambda *rows: world.replace("</apartment>", "<searchStats>" + "".join(
        f'<stat object="{o}" place="{p}" searched="{a}" found="{b}"/>' for o, p, a, b in rows)
        + "</searchStats></apartment>")
    w("stat_found_above_searched", stats((obj, place, 2, 5)), klass="numbers")
    w("stat_unknown_place", stats((obj, "nowhere", 2, 1)), klass="structure")
    w("stat_twice", stats((obj, place, 2, 1), (obj, place, 3, 1)), klass="structure")
    # (w and m append to fixed_cases' list; recordings and bags to this one)

    m("include_nul", 'name: r\ntree:\n  include: "subtrees/search.yaml\\0#note"\n', klass="nul")
    m("name_300_characters", f"name: {'n' * 300}\ntree:\n  succeed: ok\n", klass="size")
    worst = "name: worst\nutterances: ['" + "(x) " * 60 + "go']\ntree:\n  succeed: ok\n"
    m("template_60_optional_groups", worst, "accepted", klass="template")
    m("template_150_tokens", worst.replace("(x) " * 60, "(x) " * 150), klass="template")
    m("template_slots_40_words", "name: t\nparameters:\n  a: {type: string}\n"
      "  b: {type: string}\nutterances: ['" + "(x|y) " * 20 + "{a} x {b} (x) go']\n"
      "tree:\n  succeed: ok\n", "accepted", klass="template")
    m("blackboard_integer_5000_digits", "name: r\nblackboard: {n: " + "9" * 5000 + "}\n"
      "tree:\n  succeed: ok\n", klass="huge-integer")

    rec = _recording_files(version=2)

    def r2(name, klass, files=None, expect="refused", edit=None):
        f = {**rec, **(files or {})}
        if edit is not None:
            man = json.loads(f["rec/manifest.json"])
            edit(man)
            f["rec/manifest.json"] = json.dumps(man).encode()
        out.append(Case("recording", name, f, "rec", expect, klass))

    caps = rec["rec/captures.jsonl"].decode().splitlines()
    big = "9" * 5000
    r2("v2_valid", "", expect="accepted")
    r2("manifest_integer_5000_digits", "huge-integer", {"rec/manifest.json": rec[
        "rec/manifest.json"].replace(b'"version": 2', f'"version": {big}'.encode())})
    r2("captures_integer_5000_digits", "huge-integer", {"rec/captures.jsonl": (
        caps[0].replace('"index": 0', f'"index": {big}') + "\n" + caps[1] + "\n").encode()})
    r2("actions_integer_5000_digits", "huge-integer",
       {"rec/actions.jsonl": f'{{"i": {big}, "action": "say", "args": {{}}}}\n'.encode()})
    r2("frame_path_nul", "nul", {"rec/captures.jsonl": (
        caps[0].replace("_color.png", "_color.png\\u0000x") + "\n").encode()})
    for name in ("captures.jsonl", "actions.jsonl", "manifest.json"):
        r2(f"{name}_fifo", "fifo", {f"rec/{name}": ("fifo",)})
        r2(f"{name}_dev_zero", "fifo", {f"rec/{name}": ("symlink", "/dev/zero")})
        r2(f"{name}_sparse_3GB", "size", {f"rec/{name}": ("sparse", 3 << 30)})
    r2("captures_link_out", "paths", {"rec/captures.jsonl": ("symlink", "../out.jsonl"),
                                      "out.jsonl": rec["rec/captures.jsonl"]})
    r2("depth_scale_1e300", "numbers", edit=lambda d: d.update(depth_scale=1e300))
    r2("depth_scale_1e-60", "numbers", edit=lambda d: d.update(depth_scale=1e-60))
    r2("start_pose_1e300", "numbers",
       edit=lambda d: d.update(start_pose={"x": 1e300, "y": 0.0, "yaw": 0.0}))
    r2("frames_16384_square", "size", edit=lambda d: d["intrinsics"].update(
        width=16384, height=16384, cx=8191.5, cy=8191.5))
    r2("rgba_colour", "structure", {"rec/frames/000001_color.png": cv2.imencode(
        ".png", np.zeros((24, 32, 4), np.uint8))[1].tobytes()})
    r2("twenty_thousand_captures_of_one_frame", "size",
       {"rec/captures.jsonl": ((caps[0] + "\n") * 20_000).encode()}, expect="accepted")

    if _has_ros():
        def b(name, klass, files, entry="bag.mcap"):
            out.append(Case("bag", name, files, entry, "refused", klass))
        b("mcap_fifo", "fifo", {"bag.mcap": ("fifo",)})
        b("mcap_dev_zero", "fifo", {"bag.mcap": ("symlink", "/dev/zero")})
        for kind, content in (("fifo", ("fifo",)), ("dev_zero", ("symlink", "/dev/zero")),
                              ("sparse_3GB", ("sparse", 3 << 30)),
                              ("nested_30000", ("a: " + "[" * 30_000 + "]" * 30_000).encode())):
            b(f"topic_map_{kind}", "fifo" if kind in ("fifo", "dev_zero") else "size",
              {"bag.mcap": b"\x89MCAP0\r\n", "bag.topics.yaml": content})
        b("rosbag2_metadata_fifo", "fifo", {"bagdir/metadata.yaml": ("fifo",),
                                            "bagdir/x.mcap": b"\x89MCAP0\r\n"}, "bagdir")
    return out
