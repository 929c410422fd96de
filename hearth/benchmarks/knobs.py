"""Knob detection, angle and state on held-out rendered views of the knobs of the demo home
(unless ``--no-demo``), of world files and of generated homes (``--world W``, repeatable:
a file, ``demo`` or ``home:SEED``; ``--homes N``: ``home:SEED`` for seeds ``--seed`` ..
``--seed + N - 1``, hearth/worldmodel/homegen.py, knob designs varied, see ``KNOB_FAMILIES`` in homegen_knobs.py), with
the reader made for each world (its time: ``per_home[].load_or_train_s``, ``train_s_max``).

``--renderer mujoco`` draws the held-out frames with MuJoCo (hearth/robot/mujoco_render.py,
docs/renderers-and-assets.md) from the same poses and states, the reader still made from
Hearth's renders; ``renderer`` in the JSON says which drew them.

Held-out views are drawn with seeds 10000 + the home's seed (10000 + --seed for the demo and
files; training uses 1..3), 800 on the demo home and 120 on every other world by default
(``--scenarios`` for all): a camera 0.5-1.5 m
from a knob, up to 60 degrees off its axis, every knob at one of its discrete states (+- 2
degrees), 20 % of views with the knob removed (its region then must give no detection), the
map's knob pose off by registration-like errors (5 mm, 1 degree sigma), lighting, blur and
the simulated robot's Kinect noise. A detection counts when its centre is within half a knob
radius of the true one; a detection in an empty region or far from the knob is a false
positive (and, for a present knob, also a miss). ``state_accuracy`` counts "unknown" as
wrong; ``state_wrong_rate`` is the share read confidently as another state. ``hard_corner``:
recall and state accuracy of the knobs seen from beyond 1.2 m and more than 45 degrees
off-axis together (where the first models failed most).

``ms_per_knob`` is the median wall time of one knob's detection + angle + state (all of
``KnobReader.read`` for one knob), ``cpu_ms_per_knob`` the median CPU time of the same
(less inflated by other processes on a shared machine); ``ms_per_frame_all_knobs`` reads
every knob of each world's appliance with the most knobs in full 640x480 frames. Timings are taken on whatever else the machine is running (see
``load_avg_1m``). The RAMCIP reference (D3.1 6.3.5: 96 % detection, ~10 degrees, ~1.25 s
per knob) is given as ratios ours / theirs (detection: higher is better; angle and time:
lower is better). The models are the default ones (trained on first use, see docs/knobs.md).

Figures are pooled over the worlds at the top level, with ``per_world`` (the same figures per
world), ``generated`` (the generated homes alone) and ``per_home`` (each world's reader:
time to make it, its gates, headline figures). ``per_level``: the same figures by how hard
the view is for the state gates (``hearth.perception.knobs.view_level`` of the knob's true radius
in the image and its angle off-axis): ``near`` (12 px radius or more and at most 45 degrees
off-axis), ``hard`` (under 12 px or beyond 45 degrees), ``very_hard`` (under 8 px or beyond
55 degrees), so that where the reader reads and where a view is too small or oblique to
read can be told apart.
``on_read_as_off``: knobs that were on (not at their off state) read as off (must be 0).
Angle errors of a symmetric knob are taken modulo its symmetry. ``per_design``: the same
figures for each knob design (``design_of``: the roles and primitive kinds of its shape and
its symmetry, "plain" for the format-1 knob), pooled over the worlds; ``packed``: the knobs
whose nearest neighbour is at most ``PACKED_RADII`` radii away. ``state_over_views`` (also in
``generated``): state accuracy, read-wrong rate and on read as off when each knob is read
from 1, 2 or 3 of its held-out views at the same state, the first state given kept, as a
mission reads a knob from one place and then from others while it stays unknown
(``over_views``); the per-view figures above are the issue's. Each ``per_level`` entry also
says ``n`` (knobs present). ``per_family``: the same figures per design family
(``family_of``: the grip's type). ``renderer``: what drew the frames ("hearth"; ``render`` is
the one place frames are made).

``--held-out-families``: leave one design family out. ``held_out_families`` ({family:
{"near_state_accuracy", "n", ...}}): each family's views read again through gates chosen on
the other families' validation readings alone, pooled over the run's worlds
(``held_out_families``); the figures at the top level stay those of each home's own gates.
"""
from __future__ import annotations

import math
import os
import time

from typing import Optional

import numpy as np

#: Knobs whose nearest neighbour stands at most this many radii away count as ``packed``.
PACKED_RADII = 2.25
#: ``per_level`` keys, by ``hearth.perception.knobs.view_level``.
LEVELS = ("near", "hard", "very_hard")
REFERENCE = dict(detection=0.96, angle_err_deg=10.0, ms_per_knob=1250.0)


def add_arguments(parser) -> None:  # pragma: no cover - argparse wiring
    from hearth.benchmarks import _worlds
    _worlds.add_arguments(parser, homes=0)   # --world W (repeatable), --homes N, --no-demo
    from hearth.robot.mujoco_render import add_renderer_argument
    add_renderer_argument(parser)            # --renderer hearth|mujoco (held-out frames)
    parser.add_argument("--held-out-families", action="store_true",
                        help="also read each design family through gates chosen on the other "
                             "families' validation readings alone (held_out_families)")


def _wrap_deg(a: float, period: float = 2 * math.pi) -> float:
    return abs(math.degrees(math.remainder(a, period)))


def _summary(errs: list[float]) -> dict:
    e = np.asarray(errs, dtype=float)
    if len(e) == 0:
        return dict(median=None, mean=None, p95=None, p90=None)
    return dict(median=round(float(np.median(e)), 2), mean=round(float(e.mean()), 2),
                p95=round(float(np.percentile(e, 95)), 2), p90=round(float(np.percentile(e, 90)), 2))


def design_of(knob) -> str:
    """A knob design's name for the figures: "plain", or its shape's roles and primitive
    kinds and its symmetry ("base:cylinder grip:box marker:box", "... sym2")."""
    if not knob.described:
        return "plain"
    parts = []
    for role in ("base", "grip", "marker"):
        m = getattr(knob, role)
        if m is not None:
            kinds = "+".join(sorted({v.shape for v in m.visuals})) or "ref"
            parts.append(f"{role}:{kinds}" + ("(fixed)" if role == "base" and knob.base_fixed else ""))
    return " ".join(parts) + (f" sym{knob.symmetry}" if knob.symmetry > 1 else "")


def family_of(knob) -> str:
    """A knob's design family for the held-out protocol: its grip's type, "plain" for the
    format-1 knob. The type is the name of the grip's first visual where the generator named
    it by type (``hearth.worldmodel.homegen_knobs.GRIP_TYPES``), else that visual's primitive kind
    ("box", "cylinder", "mesh"); a knob without a grip is named by its marker ("marker:...")
    or base."""
    if not knob.described:
        return "plain"
    from hearth.worldmodel.homegen_knobs import GRIP_TYPES
    for role in ("grip", "marker", "base"):
        m = getattr(knob, role)
        if m is not None and m.visuals:
            v = m.visuals[0]
            if role == "grip" and v.name in GRIP_TYPES:
                return v.name
            return v.shape if role == "grip" else f"{role}:{v.shape}"
    return "plain"


def render(world, n: int, seed: int, config, noise, scenes) -> list:
    """The bench's held-out views of ``world``'s knobs (``hearth.perception.knob_data.KnobView``): a
    camera 0.5-1.5 m from a knob, every knob at one of its states, 20 % of views with the knob
    removed, drawn with ``seed``; ``config``: the reader's ``KnobConfig`` (the crop around the
    knob). ``scenes``: what draws the frames (``hearth.robot.mujoco_render.knob_scenes``:
    Hearth's own ray caster or MuJoCo, chosen with ``--renderer``). The one place the bench
    makes its frames."""
    from hearth.perception.knob_data import KnobDataConfig, render_views
    data = KnobDataConfig(at_states=True, missing_rate=0.2)
    return render_views(world, n, seed, data, config, noise=noise, scenes=scenes)


def _measure(world, reader, views, label: str, scenes) -> list[dict]:
    """One record per held-out view of ``world``'s knobs (``views``, from ``render``), read by
    ``reader``."""
    from hearth.perception.knob_data import true_center_m
    from hearth.perception.knobs import view_level
    pitch = {}
    for owner, ids in scenes.knobs_of.items():
        for a in ids:
            pa = scenes.priors[a].T_world_knob[:3, 3]
            d = [np.linalg.norm(pa - scenes.priors[b].T_world_knob[:3, 3]) for b in ids if b != a]
            pitch[a] = min(d) / scenes.priors[a].radius if d else math.inf
    out = []
    for v in views:
        t, c = time.perf_counter(), time.process_time()
        r = reader.read(v.image, v.K, v.T_world_camera, [v.believed], depth=v.depth)[0]
        ms, cpu = (time.perf_counter() - t) * 1000, (time.process_time() - c) * 1000
        hit = False
        if r.found:
            cx, cy = true_center_m(v)
            d = math.hypot(r.detection.center_m[0] - cx, r.detection.center_m[1] - cy)
            hit = v.present and d <= 0.5 * v.truth.radius
        knob = world.get(v.truth.knob_id)
        period = 2 * math.pi / max(1, v.truth.symmetry)
        out.append(dict(world=label, knob=v.truth.knob_id, design=design_of(knob),
                        family=family_of(knob),
                        present=v.present, found=r.found,
                        hit=hit, state=r.state, truth=v.state, off=knob.off,
                        err=_wrap_deg(r.angle - v.angle, period) if hit else None,
                        distance=v.distance, off_axis=v.off_axis_deg, ms=ms, cpu_ms=cpu,
                        level=LEVELS[view_level(v.K.fx * v.truth.radius / v.distance, v.off_axis_deg)],
                        radius_m=v.truth.radius, pitch_radii=pitch[v.truth.knob_id]))
    return out


def _figures(recs: list[dict]) -> dict:
    present = [r for r in recs if r["present"]]
    tp = sum(r["hit"] for r in present)
    fp = sum(r["found"] and not r["hit"] for r in recs)
    errs = [r["err"] for r in present if r["err"] is not None]
    s = _summary(errs)
    n = max(len(present), 1)
    return dict(
        views=len(recs), knobs_present=len(present), knobs_missing=len(recs) - len(present),
        n=len(present),
        detection_precision=round(tp / max(tp + fp, 1), 4),
        detection_recall=round(tp / n, 4),
        angle_err_deg_median=s["median"], angle_err_deg_mean=s["mean"],
        angle_err_deg_p90=s["p90"], angle_err_deg_p95=s["p95"],
        state_accuracy=round(sum(r["state"] == r["truth"] for r in present) / n, 4),
        state_unknown_rate=round(sum(r["state"] == "unknown" for r in present) / n, 4),
        state_wrong_rate=round(sum(r["state"] not in ("unknown", r["truth"]) for r in present) / n, 4),
        on_read_as_off=sum(r["truth"] != r["off"] and r["state"] == r["off"] for r in present),
        false_detections_empty=sum(r["found"] for r in recs if not r["present"]),
        ms_per_knob=round(float(np.median([r["ms"] for r in recs])), 2) if recs else None,
        cpu_ms_per_knob=round(float(np.median([r["cpu_ms"] for r in recs])), 2) if recs else None,
    )


def over_views(recs: list[dict], views=(1, 2, 3)) -> dict:
    """The state a knob is given when it is read from up to k views, as a mission reads it
    (``ReadKnobs`` from one place, then from the others while it stays unknown, the first
    state given kept): for each k in ``views``, each held-out view of a present knob leads
    a sequence once, followed by the next k - 1 views of the same knob of the same world at
    the same state in the bench's order (cyclically); the sequence's state is the first
    view's that is not "unknown". Knobs with fewer than k such views make no sequence
    (``sequences`` says how many were made). k = 1 is the per-view figure."""
    groups: dict = {}
    for r in recs:
        if r["present"]:
            groups.setdefault((r["world"], r["knob"], r["truth"]), []).append(r)
    out = {}
    for k in views:
        n = right = wrong = on_off = 0
        for g in groups.values():
            if len(g) < k:
                continue
            for i in range(len(g)):
                seq = [g[(i + j) % len(g)] for j in range(k)]
                state = next((r["state"] for r in seq if r["state"] != "unknown"), "unknown")
                n += 1
                right += state == g[0]["truth"]
                wrong += state not in ("unknown", g[0]["truth"])
                on_off += g[0]["truth"] != g[0]["off"] and state == g[0]["off"]
        out[str(k)] = dict(sequences=n, state_accuracy=round(right / max(n, 1), 4),
                           state_wrong_rate=round(wrong / max(n, 1), 4), on_read_as_off=on_off)
    return out


def _frames_ms(world, reader, seed: int, n: int, renderer: str = "hearth") -> list[float]:
    """Wall ms of reading every knob of the map's appliance with the most knobs in full
    640x480 frames, from 0.7-1.1 m in front of its knob panel and 0.3-0.6 m above it."""
    from hearth.perception.camera import Intrinsics, look_at
    from hearth.robot.mujoco_render import knob_scenes
    from hearth.perception.knobs import knob_priors
    K = Intrinsics.kinect()
    scenes = knob_scenes(world, renderer)
    owner = max(sorted(scenes.knobs_of), key=lambda o: len(scenes.knobs_of[o]))
    priors = knob_priors(world, owner)
    mid = np.mean([p.T_world_face()[:3, 3] for p in priors], axis=0)
    normal = priors[0].T_world_knob[:3, 2]
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        eye = mid + normal * rng.uniform(0.7, 1.1) + np.array([0, 0, rng.uniform(0.3, 0.6)])
        T_wc = look_at(eye, mid + rng.normal(0, 0.05, 3))
        angles = {p.knob_id: float(rng.choice(p.state_angles)) for p in priors}
        frame = scenes.scene(owner, angles).render(K, T_wc)
        t = time.perf_counter()
        reader.read(frame.color, K, T_wc, priors, depth=frame.depth)
        out.append((time.perf_counter() - t) * 1000)
    return out


def _world(spec: str, args, seed: int, keep: Optional[dict] = None) -> tuple[list[dict], dict]:
    """The held-out views of one world (``demo``, ``home:SEED`` or a file) and what else is
    reported of it: the reader's making, its gates, the full-frame reading time. ``keep``:
    given, the world, its reader, views and scenes are kept in it under ``spec`` (the
    held-out protocol reads the views again)."""
    from hearth.robot.mujoco_render import knob_scenes
    from hearth.skills.knob_models import _noise, load_or_train
    from hearth.benchmarks import _worlds
    world = _worlds.load(spec)
    if not world.knobs():
        return [], dict(world=spec, skipped="the world has no knob")
    t0 = time.perf_counter()
    reader, info = load_or_train(world)
    train_s = time.perf_counter() - t0
    quick = getattr(args, "quick", False)
    n = getattr(args, "scenarios", None) or ((150 if quick else 800) if spec == "demo" else
                                            (40 if quick else 120))
    renderer = getattr(args, "renderer", None) or "hearth"
    scenes = knob_scenes(world, renderer)
    views = render(world, n, seed, reader.config, _noise(), scenes)
    recs = _measure(world, reader, views, spec, scenes)
    if keep is not None:
        keep[spec] = dict(world=world, reader=reader, views=views, scenes=scenes)
    f = _figures(recs)
    return recs, dict(world=spec, knobs=len(world.knobs()),
                      designs=sorted({r["design"] for r in recs}),
                      load_or_train_s=round(train_s, 1), model_source=info.source,
                      model_path=str(info.path),
                      state_accuracy=f["state_accuracy"], detection_recall=f["detection_recall"],
                      on_read_as_off=f["on_read_as_off"],
                      detector_threshold=round(reader.detect_threshold, 4),
                      detector_calibration=getattr(reader.detect_gate, "validation_", None),
                      state_margin_threshold=round(reader.margin_threshold, 4),
                      frame_ms=_frames_ms(world, reader, seed, 3 if quick else 8, renderer))


def run(args) -> dict:
    """The figures pooled over the worlds (``--world``, ``--homes``; the demo home unless
    ``--no-demo``), ``per_world`` (``per_home``: each world's reader and headline figures),
    ``generated`` (the generated homes alone, when there are other worlds too),
    ``per_design``, ``packed`` and ``hard_corner``. Held-out views of a world are drawn with
    seed 10000 + its home seed (``home:SEED``), else 10000 + ``--seed``."""
    from hearth.benchmarks import _worlds
    specs = _worlds.world_specs(args, homes=0)
    if not specs:
        raise _worlds.NoScenes("knobs: no world to run on (--no-demo needs --world or --homes)")
    base = int(getattr(args, "seed", 0) or 0)
    held_out = bool(getattr(args, "held_out_families", False))
    kept: Optional[dict] = {} if held_out else None
    recs, per_world, frame_ms = [], [], []
    for spec in specs:
        seed = 10_000 + (int(spec.split(":", 1)[1]) if _worlds.is_generated(spec) else base)
        rs, about = _world(spec, args, seed, kept)
        recs += rs
        frame_ms += about.pop("frame_ms", [])
        per_world.append(about)
    if not recs:
        raise _worlds.NoScenes("knobs: " + "; ".join(f"{w['world']}: {w['skipped']}" for w in per_world))
    present = [r for r in recs if r["present"]]
    far_err = [r["err"] for r in present if r["err"] is not None and r["distance"] > 1.2]
    oblique_err = [r["err"] for r in present if r["err"] is not None and r["off_axis"] > 45]
    hard = [r for r in present if r["distance"] > 1.2 and r["off_axis"] > 45]
    out = _figures(recs)
    recall, med, ms = out["detection_recall"], out["angle_err_deg_median"], out["ms_per_knob"]
    read = [w for w in per_world if "skipped" not in w]
    gen = [r for r in recs if _worlds.is_generated(r["world"])]
    out.update(
        angle_method="analysis by synthesis",
        renderer=getattr(args, "renderer", None) or "hearth",
        worlds=specs, homes=sum(_worlds.is_generated(s) for s in specs),
        views_per_world={w: sum(r["world"] == w for r in recs) for w in specs},
        per_world={w["world"]: _figures([r for r in recs if r["world"] == w["world"]]) for w in read},
        per_home=per_world,
        per_design={d: _figures([r for r in recs if r["design"] == d])
                    for d in sorted({r["design"] for r in recs})},
        packed=_figures([r for r in recs if r["pitch_radii"] <= PACKED_RADII]),
        per_level={lv: _figures([r for r in recs if r["level"] == lv])
                   for lv in LEVELS if any(r["level"] == lv for r in recs)},
        per_family={f: _figures([r for r in recs if r["family"] == f])
                    for f in sorted({r["family"] for r in recs})},
        state_over_views=over_views(recs),
        angle_err_deg_median_beyond_1_2m=_summary(far_err)["median"],
        angle_err_deg_median_beyond_45deg=_summary(oblique_err)["median"],
        hard_corner=dict(knobs_present=len(hard),
                         detection_recall=round(sum(r["hit"] for r in hard) / max(len(hard), 1), 4),
                         state_accuracy=round(sum(r["state"] == r["truth"] for r in hard) / max(len(hard), 1), 4)),
        ms_per_knob_p95=round(float(np.percentile([r["ms"] for r in recs], 95)), 2),
        ms_per_frame_all_knobs=round(float(np.median(frame_ms)), 2) if frame_ms else None,
        train_s_max=max((w["load_or_train_s"] for w in read if w["model_source"] == "trained"),
                        default=None),
        load_avg_1m=round(os.getloadavg()[0], 2),
        reference_ramcip=dict(REFERENCE),
        ratio_detection_recall_vs_ramcip=round(recall / REFERENCE["detection"], 3),
        ratio_angle_err_vs_ramcip=(round(med / REFERENCE["angle_err_deg"], 3) if med is not None else None),
        ratio_ms_per_knob_vs_ramcip=round(ms / REFERENCE["ms_per_knob"], 4),
    )
    if held_out:
        out["held_out_families"] = held_out_families(kept)
    if gen and len(gen) < len(recs):
        out["generated"] = dict(_figures(gen), state_over_views=over_views(gen))
    if len(read) == 1:      # one world: its reader's gates at the top level, as before
        w = read[0]
        out.update(detector_threshold=w["detector_threshold"],
                   detector_calibration=w["detector_calibration"],
                   state_margin_threshold=w["state_margin_threshold"],
                   models=dict(source=w["model_source"], path=w["model_path"],
                               load_or_train_s=w["load_or_train_s"]))
    return out


def held_out_families(kept: dict) -> dict:
    """Leave one design family out (``family_of``): for each family F of the knobs read, every
    world's views of F's knobs read again by that world's reader (its templates: renderings
    of the described shapes, nothing tuned) through gates chosen on the validation readings
    of the other families' knobs alone, pooled over every world of the run
    (``hearth.perception.knob_training.gates_from``). Per family: ``near_state_accuracy`` and ``n``
    (knobs present in near views), the figures over every view (``all``), and ``trained_on``
    (the validation readings the gates were chosen on). A family with no other family in the
    run has no figure (``skipped``)."""
    from hearth.perception.knob_training import gates_from
    fam: dict = {}           # (world, knob id) -> family
    for spec, k in kept.items():
        for kn in k["world"].knobs():
            fam[(spec, kn.id)] = family_of(kn)
    pool = {"depth": [], "colour": []}
    for spec, k in kept.items():
        val = getattr(k["reader"], "validation_", None)
        if val is None:
            raise RuntimeError(f"knobs: the reader of {spec} keeps no validation readings "
                               "(made by an older Hearth: hearth train knobs --force)")
        for kind in pool:
            pool[kind] += [dict(r, family=fam[(spec, r["knob"])]) for r in val[kind]]
    out = {}
    for f in sorted(set(fam.values())):
        others = {kind: [r for r in rs if r["family"] != f] for kind, rs in pool.items()}
        if not others["depth"]:
            out[f] = dict(skipped="no other family to choose gates on", n=0,
                          near_state_accuracy=None)
            continue
        recs = []
        for spec, k in kept.items():
            views = [v for v in k["views"] if fam[(spec, v.truth.knob_id)] == f]
            if views:
                reader = gates_from(k["reader"], others)
                recs += _measure(k["world"], reader, views, spec, k["scenes"])
        near = _figures([r for r in recs if r["level"] == "near"])
        out[f] = dict(near_state_accuracy=near["state_accuracy"] if near["n"] else None,
                      n=near["n"], on_read_as_off=_figures(recs)["on_read_as_off"],
                      all={k: v for k, v in _figures(recs).items()
                           if k in ("n", "state_accuracy", "state_wrong_rate", "on_read_as_off",
                                    "detection_recall")},
                      per_level={lv: dict(state_accuracy=g["state_accuracy"], n=g["n"])
                                 for lv in LEVELS
                                 for g in [_figures([r for r in recs if r["level"] == lv])]
                                 if g["n"]},
                      trained_on=len(others["depth"]))
    return out
