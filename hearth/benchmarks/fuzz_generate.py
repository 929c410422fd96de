"""Generated fuzz cases: the base files (the demo world, the shipped missions, a small
recording, hostile meshes) and the seeded mutators of worlds, missions and recordings
(``mutate_world``, ``mutate_mission``, ``mutate_recording``; ``generated_cases``)."""
from __future__ import annotations

import copy
import json
import random
from typing import Any, Iterator, Optional

from hearth.benchmarks.fuzz_case import FuzzCase


# ---------------------------------------------------------------------------------------------
# Base files

def _demo_world() -> bytes:
    from hearth import demo_world_path
    return demo_world_path().read_bytes()


def _missions() -> dict[str, bytes]:
    from hearth import missions_dir
    base = missions_dir()
    return {str(p.relative_to(base)): p.read_bytes() for p in sorted(base.rglob("*.yaml"))}


_PLY = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        b"0 0 0\n0.1 0 0\n0 0.1 0\n3 0 1 2\n")

def _tiny_png() -> bytes:
    import zlib
    import struct

    def chunk(kind: bytes, body: bytes) -> bytes:
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00\xff\x00\x00")) + chunk(b"IEND", b""))


_OBJ = b"v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n"

#: What sits next to a fuzzed world file: meshes a hostile path may name, and meshes whose
#: contents are hostile (issue 44: material libraries and textures out of the folder or FIFOs,
#: counts that allocate gigabytes, non-finite vertices, formats naming external files).
WORLD_NEIGHBOURS: dict[str, Any] = {
    "ok.ply": _PLY, "sub/inner.ply": _PLY, "emptydir": ("dir",), "fifo.ply": ("fifo",),
    "escape.ply": ("symlink", "/etc/passwd"), "etc": ("symlink", "/etc"),
    "ok.obj": b"mtllib ok.mtl\n" + _OBJ, "ok.mtl": b"newmtl a\nKd 1 0 0\nmap_Kd tex.png\n", "tex.png": _tiny_png(),
    "passwd.obj": b"mtllib ../../../../../../etc/passwd\n" + _OBJ,
    "pipe.mtl": ("fifo",), "fifo_mtl.obj": b"mtllib pipe.mtl\n" + _OBJ,
    "tex.mtl": b"newmtl a\nmap_Kd -s 1 1 1 ../../../../etc/shadow\n",
    "texture.obj": b"mtllib tex.mtl\n" + _OBJ,
    "nan.obj": b"v nan 0 0\n" + _OBJ,
    "huge.ply": _PLY.replace(b"element vertex 3", b"element vertex 2000000000"),
    "nan.ply": _PLY.replace(b"0 0 0\n0.1 0 0", b"nan 0 0\ninf 0 0"),
    "truncated.ply": _PLY[:-12],
    "m.gltf": b'{"buffers": [{"uri": "/etc/passwd"}]}',
}
#: The neighbours whose contents are hostile (mesh-content class).
HOSTILE_MESHES = ["passwd.obj", "fifo_mtl.obj", "texture.obj", "nan.obj", "huge.ply",
                  "nan.ply", "truncated.ply", "m.gltf"]
#: The utterance that froze the server against a template of 60 optional groups (issue 44).
WORST_UTTERANCE = "x " * 21 + "y"


def _recording_files(n: int = 2, width: int = 32, height: int = 24,
                     version: int = 1) -> dict[str, Any]:
    """A small valid recording, written per docs/recording-format.md (not through Hearth's
    writer, so the reader is tested against the documented format): ``version`` 1 (all in
    manifest.json) or 2 (captures.jsonl and actions.jsonl beside it)."""
    import cv2
    import numpy as np
    files: dict[str, Any] = {}
    caps = []
    for i in range(n):
        color = np.full((height, width, 3), 40 * (i + 1), np.uint8)
        depth = np.full((height, width), 1500 + 10 * i, np.uint16)
        ok1, c = cv2.imencode(".png", color)
        ok2, d = cv2.imencode(".png", depth)
        files[f"rec/frames/{i:06d}_color.png"] = c.tobytes()
        files[f"rec/frames/{i:06d}_depth.png"] = d.tobytes()
        T = [[0, 0, 1, 1.0 + i], [-1, 0, 0, 2.0], [0, -1, 0, 1.2], [0, 0, 0, 1]]
        caps.append({"index": i, "timestamp": 1.5 * i, "color": f"frames/{i:06d}_color.png",
                     "depth": f"frames/{i:06d}_depth.png",
                     "base_pose": {"x": 1.0 + i, "y": 2.0, "yaw": 0.0}, "T_world_camera": T,
                     "pan": 0.0, "tilt": 0.3, "parking": None, "goal": None, "truth": None})
    manifest = {"format": "hearth-recording", "version": 1, "depth_scale": 0.001,
                "intrinsics": {"fx": 30.0, "fy": 30.0, "cx": (width - 1) / 2,
                               "cy": (height - 1) / 2, "width": width, "height": height},
                "info": {"mission": "fuzz"}, "start_pose": {"x": 1.0, "y": 2.0, "yaw": 0.0},
                "captures": caps, "actions": []}
    if version == 2:
        manifest.update(version=2, captures="captures.jsonl", actions="actions.jsonl")
        files["rec/captures.jsonl"] = "".join(json.dumps(c) + "\n" for c in caps).encode()
        files["rec/actions.jsonl"] = (b'{"i": 0, "time": 1.0, "action": "say", "args": {}}\n'
                                      b'{"i": 0, "status": "succeeded", "reason": ""}\n')
    files["rec/manifest.json"] = json.dumps(manifest, indent=1).encode()
    return files


# ---------------------------------------------------------------------------------------------
# Mutators

HOSTILE_NUMBERS = ["NaN", "INF", "-INF", "1e308", "-1e308", "1e999", "1e-400", "0", "-0", "-1",
                   "10000", "10000.000001", "-10000.5", "5e-324", "", " ", "abc", "1,5", "0x10",
                   "1_0", "9" * 400, "+.5", "1 2", "1 2 3 4", "NaN NaN NaN", "0 0 0",
                   "1e308 0 0", "-1 -1 -1", "1e5", "3.4e38", "2", "0.5 0.5 0.5", "INF 0 0"]
HOSTILE_PATHS = ["../../etc/passwd", "/etc/passwd", "/dev/zero", "/proc/self/environ",
                 "../../../../proc/self/maps", "emptydir", "escape.ply", "fifo.ply", "ok.ply",
                 "missing.ply", "./ok.ply", "sub/../ok.ply", "sub/../../x.ply", "~/x.ply",
                 "C:\\x.ply", "etc/passwd", "sub/inner.ply", "//etc/passwd", ".", "",
                 "ok.obj", *HOSTILE_MESHES]
HOSTILE_TEXT = ["", " ", "x" * 5000, "\u202e", "\u00e9t\u00e9", "a b", "<", "&", "1abc", "_",
                "a" * 4097, "kitchen", "no_such_cup", "no_such_knob_1", "\U0001F600", "true", "off"]
_ATTRS = ["x", "y", "z", "roll", "pitch", "yaw", "radius", "length", "size", "scale", "color",
          "file", "pointcloud", "bounds", "lower", "upper", "state", "angle", "axis", "sizeX",
          "sizeY", "standoff", "depth", "id", "type", "default", "time", "searched", "found",
          "version", "ref", "on", "graspable", "markerColor", "off", "relation", "name"]


def _world_value(rng: random.Random, old: Optional[str]) -> str:
    r = rng.random()
    if r < 0.55:
        return rng.choice(HOSTILE_NUMBERS)
    if r < 0.7:
        return rng.choice(HOSTILE_PATHS)
    if r < 0.85:
        return rng.choice(HOSTILE_TEXT)
    return repr(rng.uniform(-1, 1) * 10 ** rng.randint(-5, 12))


def mutate_world(rng: random.Random, base: bytes) -> tuple[str, bytes]:
    """One mutated world file (and a short description of what was done)."""
    from lxml import etree
    root = etree.fromstring(base)
    els = [e for e in root.iter() if isinstance(e.tag, str)]
    done = []
    for _ in range(rng.choice((1, 1, 1, 2, 3))):
        el = rng.choice(els)
        op = rng.random()
        if op < 0.45:
            attr = rng.choice(list(el.attrib) or _ATTRS) if rng.random() < 0.75 else rng.choice(_ATTRS)
            value = _world_value(rng, el.get(attr))
            el.set(attr, value)
            done.append(f"{el.tag}@{attr}={value[:20]!r}")
        elif op < 0.52 and el.attrib:
            attr = rng.choice(list(el.attrib))
            del el.attrib[attr]
            done.append(f"del {el.tag}@{attr}")
        elif op < 0.60 and el.getparent() is not None:
            el.getparent().remove(el)
            done.append(f"del <{el.tag}>")
        elif op < 0.67 and el.getparent() is not None:
            el.addnext(copy.deepcopy(el))
            done.append(f"dup <{el.tag}>")
        elif op < 0.72:
            target = rng.choice(els)
            if el is not root and target is not el and el not in target.iterancestors():
                target.append(el)
                done.append(f"move <{el.tag}> into <{target.tag}>")
        elif op < 0.76:
            tag = rng.choice(["room", "part", "mesh", "box", "knob", "pose", "x", "SmallObject"])
            done.append(f"rename <{el.tag}> to <{tag}>")
            el.tag = tag
        elif op < 0.86:
            models = [e for e in els if e.tag == "model"] or [root]
            m = rng.choice(models)
            path = rng.choice(HOSTILE_PATHS)
            etree.SubElement(m, "mesh", file=path, color="0.5 0.5 0.5")
            done.append(f"mesh file={path!r}")
        elif op < 0.90:
            rooms = [e for e in els if e.tag == "room"]
            path = rng.choice(HOSTILE_PATHS)
            rng.choice(rooms).set("pointcloud", path)
            done.append(f"pointcloud={path!r}")
        elif op < 0.93:
            parent = rng.choice([e for e in els if e.tag in ("LargeArticulatedObject", "part")]
                                or [root])
            depth = rng.randint(2, 60)
            cur = parent
            for i in range(depth):
                cur = etree.SubElement(cur, "part", id=f"fz_{rng.randint(0, 10**9)}_{i}",
                                       type="door")
                etree.SubElement(cur, "joint", type="fixed")
            done.append(f"{depth} nested parts")
        elif op < 0.95:
            n = rng.choice((10, 200, 1200))
            room = rng.choice([e for e in els if e.tag == "room"])
            for i in range(n):
                c = copy.deepcopy(room)
                for e in c.iter():
                    if "id" in e.attrib:
                        e.set("id", f"{e.get('id')}_c{i}")
                room.addnext(c)
            done.append(f"{n} room copies")
        else:
            descs = [e for e in els if e.tag == "description"] or [el]
            d = rng.choice(descs)
            d.text = rng.choice(HOSTILE_TEXT)
            done.append(f"text of <{d.tag}>")
    data = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    if rng.random() < 0.15:
        data, what = _mutate_bytes(rng, data, [b"<!DOCTYPE a [<!ENTITY x SYSTEM 'file:///etc/passwd'>]>",
                                               b"&x;", b"<![CDATA[", b"\xff\xfe", b"\x00",
                                               b"<a>" * 300])
        done.append(what)
    return "; ".join(done) or "unchanged", data


def _mutate_bytes(rng: random.Random, data: bytes, tokens: list[bytes]) -> tuple[bytes, str]:
    op = rng.random()
    if op < 0.3:
        cut = rng.randrange(len(data))
        return data[:cut], f"truncated at {cut}"
    if op < 0.6:
        b = bytearray(data)
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        return bytes(b), "flipped bytes"
    pos = rng.randrange(len(data))
    tok = rng.choice(tokens)
    return data[:pos] + tok + data[pos:], f"inserted {tok[:20]!r}"


_DEEP = None


def _mission_value(rng: random.Random):
    r = rng.random()
    pool = [float("nan"), float("inf"), -float("inf"), 10**26, -1, 0, 1e308, 2**63, 2**64 + 1,
            "", "x" * 5000, None, True, [], {}, [1, 2], {"x": float("nan"), "y": 0},
            "{missing}", "$missing", "/etc/passwd", "../../etc/passwd#x", "/dev/zero#x",
            "/proc/self/environ#x", "subtrees/search.yaml#nope", "subtrees/search.yaml",
            "../missions/go_to_rest.yaml", "subtrees", 1.5, "sequence", {"succeed": None},
            {"inverter": {"succeed": "x"}}, 3, 1000, 1001, 86400, 86401, 1e-300, "1e400",
            "{x} < .nan", "$presence == home", "not {x}", "[1, 2", "{a: [}", 0.0, -0.0,
            "subtrees/search.yaml\x00#note", "a\x00b", "n" * 300, 10 ** 4000]
    if r < 0.9:
        return copy.deepcopy(rng.choice(pool))
    value: Any = "x"
    for _ in range(rng.randint(20, 250)):
        value = [value]
    return value


def _yaml_classes():
    import yaml
    return (getattr(yaml, "CSafeLoader", yaml.SafeLoader),
            getattr(yaml, "CSafeDumper", yaml.SafeDumper))


_YAML_LOADER, _YAML_DUMPER = _yaml_classes()

_KINDS = ["sequence", "selector", "parallel", "retry", "timeout", "repeat", "inverter",
          "force_success", "force_failure", "for_each", "guard", "watch", "skill", "condition",
          "succeed", "fail", "include", "state_machine"]


def _paths(data, prefix=()):
    """Every (container, key) in a plain YAML structure."""
    out = []
    stack = [data]
    while stack:
        cur = stack.pop()
        if isinstance(cur, dict):
            for k, v in cur.items():
                out.append((cur, k))
                stack.append(v)
        elif isinstance(cur, list):
            for i, v in enumerate(cur):
                out.append((cur, i))
                stack.append(v)
    return out


def mutate_mission(rng: random.Random, files: dict[str, bytes]) -> tuple[str, dict[str, bytes], str]:
    """One mutated copy of the shipped missions: (description, files, entry)."""
    import yaml
    names = sorted(n for n in files if "/" not in n)
    entry = rng.choice(names)
    target = entry
    if rng.random() < 0.2 and b"subtrees/search.yaml" in files[entry]:
        target = "subtrees/search.yaml"
    out = dict(files)
    done = []
    if rng.random() < 0.75:
        data = yaml.load(files[target], Loader=_YAML_LOADER)
        for _ in range(rng.choice((1, 1, 2, 3))):
            spots = _paths(data)
            if not spots:
                break
            cont, key = rng.choice(spots)
            op = rng.random()
            if op < 0.45:
                cont[key] = _mission_value(rng)
                done.append(f"{key!r} := {str(cont[key])[:30]!r}")
            elif op < 0.55:
                del cont[key]
                done.append(f"del {key!r}")
            elif op < 0.62 and isinstance(cont, list):
                cont.insert(key, copy.deepcopy(cont[key]))
                done.append(f"dup [{key}]")
            elif op < 0.72 and isinstance(cont, dict) and key in _KINDS:
                new = rng.choice(_KINDS)
                cont[new] = cont.pop(key)
                done.append(f"kind {key} -> {new}")
            elif op < 0.85 and isinstance(cont[key], dict):
                wrap = rng.choice(["retry", "timeout", "repeat", "inverter", "parallel"])
                node: dict = {wrap: cont[key] if wrap != "parallel" else [cont[key]]}
                extra = {"retry": "times", "timeout": "seconds", "repeat": "times",
                         "parallel": "threshold"}.get(wrap)
                if extra:
                    node[extra] = rng.choice([float("nan"), float("inf"), 10**26, 0, -1, 3, 1000,
                                              1001, 86400.5, 1e-9, "3", True, None])
                    if wrap == "parallel":
                        node["policy"] = "threshold"
                cont[key] = node
                done.append(f"wrap in {wrap}")
            elif op < 0.88 and isinstance(data, dict):
                k = rng.choice((3, 30, 60, 99, 200))
                params = data.get("parameters")     # an earlier mutation may have made it a number
                params = params if isinstance(params, dict) and params else {"nope": 0}
                data["utterances"] = [rng.choice([
                    "(x) " * k + "go", "(x|y) " * k + "{%s} go" % rng.choice(list(params)),
                    "{a} {b}", "(" + "|".join(["x"] * k) + ") go", "", "\x00", "(" * k,
                    "x" * (100 * k)])]
                done.append(f"utterance of {k} groups")
            elif op < 0.92 and isinstance(cont[key], dict):
                n = rng.choice((2, 50, 2500))
                cont[key] = {"sequence": [copy.deepcopy(cont[key]) for _ in range(n)]}
                done.append(f"{n} copies")
            else:
                cont[key] = {"include": rng.choice(["/etc/passwd#x", "../../etc/passwd",
                                                    "/proc/self/environ#x", "/dev/zero#x",
                                                    "subtrees/search.yaml#find_object",
                                                    "subtrees/search.yaml#nope", "nope",
                                                    "subtrees/", "go_to_rest.yaml",
                                                    f"{entry}#x", entry])}
                done.append("include")
        try:
            text = yaml.dump(data, Dumper=_YAML_DUMPER, sort_keys=False, allow_unicode=True,
                             width=1000)
        except (yaml.YAMLError, RecursionError):
            text = files[target].decode()
        raw = text.encode("utf-8", "surrogatepass")
    else:
        raw = files[target]
    if rng.random() < 0.35 or not done:
        tokens = [b"\n  bomb: &a [x, x, x, x, x, x, x, x, x]\n  b2: &b [*a, *a, *a, *a, *a, *a, *a, *a]\n"
                  b"  b3: &c [*b, *b, *b, *b, *b, *b, *b, *b]\n  b4: [*c, *c, *c, *c, *c, *c, *c]\n",
                  b"&a", b"*a", b"*b", b" !!python/object/apply:os.system ['true']", b" !!binary aGk=",
                  b" !!set {a, b}", b" 2001-12-14", b"\t", b"%YAML 1.1\n---\n", b"\n---\n", b"<<: *a",
                  b" .nan", b" .inf", b" 1e400", b" 0x7fffffffffffffffffff", b" " + b"9" * 5000,
                  b"\xff\xfe", b"\x00", b"\xef\xbb\xbf", b"? [a, b]\n: c\n", b"[" * 500,
                  b"{" * 2000, b"\n" + b"  " * 300 + b"x: 1\n"]
        raw, what = _mutate_bytes(rng, raw, tokens)
        done.append(what)
    out[target] = raw
    return "; ".join(done), out, entry


_REC_VALUES = [float("nan"), float("inf"), -float("inf"), 0, -1, 0.0, 1e308, -1e308, 10**30,
               "", "x", None, True, [], {}, [1, 2, 3], [[1, 0, 0, 0]] * 4, "/etc/passwd",
               "../../etc/passwd", "/dev/zero", "frames", "../rec/frames/000000_color.png",
               "frames/000001_depth.png", 65536, 2**31, 1e-12, -0.0, 640, 480, "NaN"]


def mutate_recording(rng: random.Random, base: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """One mutated recording: manifest fields and frames."""
    import cv2
    import numpy as np
    files = dict(base)
    manifest = json.loads(base["rec/manifest.json"])
    done = []
    for _ in range(rng.choice((1, 1, 2))):
        op = rng.random()
        if op < 0.6:
            spots = _paths(manifest)
            cont, key = rng.choice(spots)
            if rng.random() < 0.8:
                cont[key] = copy.deepcopy(rng.choice(_REC_VALUES))
                done.append(f"{key!r} := {str(cont[key])[:30]!r}")
            else:
                del cont[key]
                done.append(f"del {key!r}")
        else:
            frames = sorted(k for k, v in files.items()
                            if k.startswith("rec/frames/") and isinstance(v, bytes))
            if not frames:
                continue
            f = rng.choice(frames)
            kind = rng.random()
            if kind < 0.2:
                del files[f]
                done.append(f"deleted {f}")
            elif kind < 0.4:
                files[f] = files[f][:rng.randrange(len(files[f]))]
                done.append(f"truncated {f}")
            elif kind < 0.55:
                b = bytearray(files[f])
                for _ in range(8):
                    b[rng.randrange(len(b))] = rng.randrange(256)
                files[f] = bytes(b)
                done.append(f"corrupted {f}")
            elif kind < 0.7:
                img = np.zeros((rng.choice((24, 10)), rng.choice((32, 7)), rng.choice((1, 3))),
                               rng.choice((np.uint8, np.uint16)))
                files[f] = cv2.imencode(".png", img)[1].tobytes()
                done.append(f"replaced {f} by {img.shape} {img.dtype}")
            elif kind < 0.8:
                files[f] = ("dir",)
                done.append(f"{f} is a directory")
            elif kind < 0.9:
                files[f] = ("symlink", "/etc/passwd")
                done.append(f"{f} links to /etc/passwd")
            else:
                files[f] = ("fifo",)
                done.append(f"{f} is a FIFO")
    files["rec/manifest.json"] = json.dumps(manifest).encode()
    if "rec/captures.jsonl" in files and rng.random() < 0.3:    # version 2's own files
        name = rng.choice(["rec/captures.jsonl", "rec/actions.jsonl", "rec/manifest.json"])
        op = rng.random()
        if op < 0.4 and isinstance(files[name], bytes):
            files[name], what = _mutate_bytes(rng, files[name], [
                b"9" * 5000, b"-" + b"9" * 41, b"\\u0000", b"\\ud800", b"1e400", b"NaN",
                b"[" * 3000, b"\n{}\n", b"\x00"])
            done.append(f"{name}: {what}")
        elif op < 0.55:
            files[name] = ("fifo",)
            done.append(f"{name} is a FIFO")
        elif op < 0.7:
            files[name] = ("symlink", rng.choice(["/dev/zero", "/etc/passwd", "../x"]))
            done.append(f"{name} is a link out")
        elif op < 0.8:
            files[name] = ("sparse", rng.choice((1 << 20, 200 << 20, 3 << 30)))
            done.append(f"{name} is sparse")
        else:
            files[name] = ("dir",)
            done.append(f"{name} is a directory")
    if rng.random() < 0.1:
        files["rec/manifest.json"], what = _mutate_bytes(
            rng, files["rec/manifest.json"], [b"NaN", b"Infinity", b"[" * 5000, b"\xff"])
        done.append(what)
    return "; ".join(done), files


# ---------------------------------------------------------------------------------------------
# Generated cases

def generated_cases(loader: str, n: int, seed: int) -> Iterator[FuzzCase]:
    """``n`` mutated cases for ``loader``, the same ones for the same seed (made one at a time:
    some are megabytes)."""
    rng = random.Random(f"{loader}:{seed}")
    if loader == "world":
        base = _demo_world()
        for _ in range(n):
            what, data = mutate_world(rng, base)
            yield FuzzCase("world", what, {**WORLD_NEIGHBOURS, "world.xml": data}, "world.xml")
    elif loader == "mission":
        base = _missions()
        for _ in range(n):
            what, files, entry = mutate_mission(rng, base)
            yield FuzzCase("mission", what, files, entry)
    elif loader == "recording":
        bases = (_recording_files(), _recording_files(version=2))
        for i in range(n):
            what, files = mutate_recording(rng, bases[i % 2])
            yield FuzzCase("recording", what, files, "rec")
