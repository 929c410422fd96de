"""Knobs of generated appliances: discrete states with an off state under many names
(``_knob_states``), a design space of bases, grips, markers and materials (``KNOB_FAMILIES``,
``GRIP_TYPES``, ...; ``_knob_design``) and a row of knobs on a panel (``_knobs``)."""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable, Optional

import numpy as np

from hearth.worldmodel.homegen_geometry import extrude, fan_prism, frustum
from hearth.worldmodel.homegen_palette import KNOB_DESIGNS, OFF_NAMES
from hearth.worldmodel.homegen_pieces import TAU, box, _Ctx, cyl, _deg, _mm
from hearth.worldmodel.nodes import Knob, KnobState, Model, Visual
from hearth.worldmodel.pose import Pose


# The knob frame's axes in its parent's frame: on a front face whose outward normal is +x
# (knob x = parent y, marker at angle 0 = parent z, axis = parent x), and on a top face
# (axis up, marker at angle 0 pointing away from the front, -x).
_R_FRONT = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _knob_states(ctx: _Ctx, symmetry: int = 1) -> tuple[list[KnobState], str, bool, float]:
    """2-12 discrete states turning either way; the off state named one of OFF_NAMES, at
    angle 0 or not, listed first, last or in the middle. A knob whose shape repeats every
    360/``symmetry`` degrees keeps all its states within that (so no two look the same).
    Returns (states in file order, off state name, whether the off state must be named
    explicitly, the direction it turns: -1 clockwise, +1 counter-clockwise)."""
    n = ctx.i(*ctx.cfg.knob_states)
    off = ctx.pick(OFF_NAMES)
    style = ctx.pick(["digits", "temperatures", "words", "digits max"])
    if style == "words" and n <= 4:
        others = ["low", "medium", "high"][:n - 1]
    elif style == "temperatures" and n <= 10:
        start = ctx.pick([50, 80, 100])
        others = [str(start + 25 * i) for i in range(n - 1)]
    elif style == "digits max" and n >= 3:
        others = [str(i) for i in range(1, n - 1)] + ["max"]
    else:
        others = [str(i) for i in range(1, n)]
    if off in others:
        off = "off"
    if off == "min":                          # "min" cannot sit beside "max" as its opposite
        others = [o for o in others if o != "max"] + (["high"] if "max" in others else [])
        if len(set(others)) < len(others):
            others = [str(i) for i in range(1, n)]
    direction = ctx.pick([-1.0, 1.0])
    step = math.radians(ctx.u(20, 45))
    step = min(step, math.radians(300) / max(n - 1, 1))
    if symmetry > 1:
        step = min(step, math.radians(340 / symmetry) / n)
    a0 = 0.0 if ctx.chance(0.75) else ctx.pick([-1.0, 1.0]) * math.radians(ctx.pick([30, 45, 90]))
    if abs(a0) > 0 and abs(a0) + step * (n - 1) > math.radians(320):
        a0 = 0.0
    off_state = KnobState(off, _deg(a0))
    drng = ctx.design_rng or ctx.rng     # knob design draws: the rest of the home unchanged
    if len(others) >= 2 and drng.random() < ctx.cfg.off_mid_travel_probability:
        # off in the middle of the travel (a selector: settings either side of off); such a
        # knob turns either way (``direction`` 0)
        k = int(drng.integers(1, len(others)))
        states = ([KnobState(nm, _deg(a0 - direction * step * (k - i))) for i, nm in enumerate(others[:k])]
                  + [KnobState(nm, _deg(a0 + direction * step * (i + 1))) for i, nm in enumerate(others[k:])])
        return states[:k] + [off_state] + states[k:], off, True, 0.0
    states = [KnobState(nm, _deg(a0 + direction * step * (i + 1))) for i, nm in enumerate(others)]
    order = ctx.rng.random()
    if order < 0.6:
        listed = [off_state] + states
    elif order < 0.85:
        listed = states + [off_state]
    else:
        k = ctx.i(1, max(1, len(states) - 1)) if len(states) > 1 else 1
        listed = states[:k] + [off_state] + states[k:]
    explicit = not (off == "off" and listed[0] is off_state and ctx.chance(0.5))
    return listed, off, explicit, direction


#: The knob design space ``_knob_design`` draws from (docs/world-format.md, "Knobs"): a knob is
#: a base (BASE_TYPES: none, a disc or a skirt turning with it, a bezel fixed on the panel) at a
#: stand-off from the panel (flush to a few mm), a grip (GRIP_TYPES) and a marker
#: (MARKER_TYPES: a line, a dot, a tip at the end of a bar or fin, a printed pointer, or none
#: of its own: a fixed printed dial ring with ticks around a grip whose shape shows its angle,
#: or the shape alone), in materials (MATERIAL_STYLES: a marker that stands out, low
#: contrast, dark on dark, metallic). ``plain_probability`` of knobs are the format-1 knob.
#: Until generator version 4 the knobs came in five families (plain, bar, tip, pointer, skirt).
KNOB_FAMILIES = ("plain", "bar", "tip", "pointer", "skirt")
BASE_TYPES = ("none", "disc", "skirt", "bezel")
GRIP_TYPES = ("cylinder", "bar", "fin", "d-shape", "knurled", "tapered")
MARKER_TYPES = ("line", "dot", "tip", "printed", "dial", "none")
MATERIAL_STYLES = ("contrast", "low-contrast", "dark-on-dark", "metallic")
#: markers each grip can carry: a round grip needs a marker of its own; a bar or fin alone
#: reads modulo half a turn (symmetry 2); a D shows its angle by its flat
_MARKERS_OF = {"cylinder": ("line", "dot", "printed"), "knurled": ("line", "dot", "printed"),
               "tapered": ("line", "dot", "printed"), "bar": ("tip", "line", "printed", "dial", "none"),
               "fin": ("tip", "line", "dial", "none"), "d-shape": ("line", "dot", "printed", "dial", "none")}
_KNOB_COLOURS = [(0.9, 0.9, 0.88), (0.08, 0.08, 0.09), (0.74, 0.75, 0.77), (0.93, 0.88, 0.75),
                 (0.15, 0.15, 0.16), (0.55, 0.56, 0.6)]
_MARKER_COLOURS = [(0.85, 0.1, 0.1), (0.95, 0.55, 0.05), (0.1, 0.35, 0.85), (0.05, 0.05, 0.05),
                   (0.95, 0.95, 0.92)]
_METALLIC = [(0.74, 0.75, 0.77), (0.82, 0.82, 0.84), (0.62, 0.6, 0.55)]


def _distinct(a, b, by: float = 0.6) -> bool:
    """Colours the eye tells apart (L1 distance of RGB over ``by``)."""
    return sum(abs(x - y) for x, y in zip(a, b)) > by


def _contrast(drng, body, palette):
    """A colour of ``palette`` that differs from ``body`` (a marker the eye can tell)."""
    ok = [c for c in palette if _distinct(c, body)] or palette
    return ok[int(drng.integers(len(ok)))]


def _near_colour(drng, body, lo: float = 0.3, hi: float = 0.45):
    """A colour of low contrast with ``body``: every channel moved the same way (lighter on a
    dark body, darker on a light one), L1 distance ``lo``-``hi`` in all."""
    d = float(drng.uniform(lo, hi)) / 3
    sign = 1.0 if sum(body) < 1.5 else -1.0
    return tuple(round(min(1.0, max(0.0, c + sign * d)), 3) for c in body)


def _colours(drng, style: str):
    """(body, grip, marker, material) of a material style (MATERIAL_STYLES)."""
    if style == "metallic":
        body = _METALLIC[int(drng.integers(len(_METALLIC)))]
        mark = _contrast(drng, body, _MARKER_COLOURS) if drng.random() < 0.6 else _near_colour(drng, body, 0.35, 0.5)
        return body, body, mark, "shiny"
    if style == "dark-on-dark":
        body = (0.08, 0.08, 0.09) if drng.random() < 0.5 else (0.15, 0.15, 0.16)
        return body, body, _near_colour(drng, body, 0.3, 0.45), "matte"
    body = _KNOB_COLOURS[int(drng.integers(len(_KNOB_COLOURS)))]
    if style == "low-contrast":
        return body, body, _near_colour(drng, body), "matte"
    grip = body if drng.random() < 0.6 else _contrast(drng, body, _KNOB_COLOURS)
    mark = _contrast(drng, body, _MARKER_COLOURS)
    if not _distinct(mark, grip):
        mark = next(c for c in _MARKER_COLOURS if _distinct(c, body) and _distinct(c, grip))
    return body, grip, mark, "matte"


def _grip_mesh(ctx: _Ctx, kind: str, rg: float, z0: float, z1: float, drng):
    """The grip of ``kind`` (mesh grips) of radius ``rg`` from z0 to z1 (knob frame)."""
    rg = rg - 0.0002            # within rg once the vertices are rounded to 0.1 mm
    if kind == "d-shape":
        cut = rg * float(drng.uniform(0.45, 0.7))       # the flat, towards -y (the back of the D)
        t0 = -math.asin(cut / rg)
        ts = np.linspace(t0, math.pi - t0, 16)          # the round part through +y
        rq = rg
        poly = [(round(rq * math.cos(t), 4), round(rq * math.sin(t), 4)) for t in ts]
        poly += [(round(-rq * math.cos(t0), 4), round(-cut, 4)), (round(rq * math.cos(t0), 4), round(-cut, 4))]
        return ctx.meshes.add("knob-d", extrude(_ccw(poly), z0, z1))
    if kind == "knurled":
        n = int(drng.integers(16, 31))
        a = np.linspace(0, TAU, 2 * n, endpoint=False)
        rr = np.where(np.arange(2 * n) % 2 == 0, rg, rg * 0.93)
        poly = np.c_[rr * np.cos(a), rr * np.sin(a)]
        return ctx.meshes.add("knob-knurled", fan_prism(np.round(poly, 4), z0, z1))
    top = rg * float(drng.uniform(0.6, 0.8))           # tapered: narrower at its front
    return ctx.meshes.add("knob-tapered", frustum(rg, top, z0, z1))


def _knob_design(ctx: _Ctx, r: float, depth: float) -> dict:
    """The shape fields of a ``Knob`` drawn from the design space (above) with outline radius
    ``r`` and front ``depth`` (m): base, grip and marker models in the knob frame at angle 0
    (+y: the pointer), base_fixed, symmetry; and ``design`` (what was drawn, for the docs and
    the bench). Everything comes from ``design_rng``."""
    drng = ctx.design_rng or ctx.rng
    u = lambda lo, hi: float(drng.uniform(lo, hi))
    pick = lambda seq: seq[int(drng.integers(len(seq)))]
    grip_kind = pick(GRIP_TYPES)
    marker_kind = pick(_MARKERS_OF[grip_kind])
    base_kind = pick(BASE_TYPES)
    if marker_kind == "dial":
        base_kind = "bezel"                              # the printed ring stays on the panel
    style = pick(MATERIAL_STYLES)
    if marker_kind in ("tip", "printed") and style in ("low-contrast", "dark-on-dark"):
        # a tip is the bar's own end and a printed pointer has no relief: only their colour
        # tells them
        style = "contrast"
    body, grip_c, mark, material = _colours(drng, style)
    standoff = 0.0 if drng.random() < 0.5 else _mm(u(0.0005, 0.003))   # flush .. 3 mm off
    # the base: how thick it is (a flat disc down to 1 mm) and how wide the grip on it is
    hb = {"none": 0.0, "disc": _mm(max(0.001, depth * u(0.05, 0.4))),
          "skirt": _mm(depth * u(0.25, 0.45)), "bezel": _mm(u(0.001, 0.004))}[base_kind]
    rg = r if base_kind == "none" else r * (u(0.55, 0.75) if base_kind in ("skirt", "bezel") else u(0.7, 0.95))
    if grip_kind in ("bar", "fin") and base_kind in ("disc", "none"):
        rg = 0.95 * r                                    # a bar across its disc
    z_base0 = 0.0 if base_kind == "bezel" else standoff  # a bezel sits on the panel
    z_grip0 = standoff + (hb if base_kind in ("disc", "skirt") else 0.0)
    z_grip0 = max(z_grip0, hb if base_kind == "bezel" else 0.0)
    z1 = max(depth, z_grip0 + 0.004)
    hg = z1 - z_grip0
    zc = z_grip0 + hg / 2
    sym = 1
    out: dict = dict(design=dict(base=base_kind, grip=grip_kind, marker=marker_kind, material=style,
                                 standoff_mm=round(standoff * 1000, 1)))
    base_vis = []
    if base_kind != "none":
        ring_c = body if base_kind != "bezel" else _contrast(drng, body, _KNOB_COLOURS)
        base_vis.append(cyl(r, hb, z=z_base0 + hb / 2, color=ring_c, material=material, name=base_kind))
        if marker_kind == "dial":
            # ticks printed on the fixed ring between the grip and its rim, every 30 degrees
            # or at 8-12 evenly spaced places; numbers are ticks of another length here
            n_ticks = int(drng.integers(8, 13))
            tick_c = _contrast(drng, ring_c, _MARKER_COLOURS)
            tl = (r - rg) * 0.6
            for i in range(n_ticks):
                a = TAU * i / n_ticks
                ym = rg + (r - rg) * 0.5
                base_vis.append(Visual("box", Pose(_mm(-ym * math.sin(a)), _mm(ym * math.cos(a)),
                                                   _mm(z_base0 + hb + 0.00015), 0, 0, round(a, 4)),
                                       size=(_mm(max(0.0008, r * 0.05)), _mm(max(tl, 0.002)), 0.0003),
                                       color=tick_c, name="tick"))
    if grip_kind == "cylinder":
        grip = cyl(rg, hg, z=zc, color=grip_c, material=material, name="cylinder")
        top_r = rg
    elif grip_kind in ("bar", "fin"):
        w = r * (u(0.28, 0.4) if grip_kind == "bar" else u(0.1, 0.18))
        length = 2 * rg
        if marker_kind == "tip":
            tl = r * u(0.25, 0.4)
            grip = box(w, length - tl, hg, y=-tl / 2, z=zc, color=grip_c, material=material, name=grip_kind)
        else:
            grip = box(w, length, hg, z=zc, color=grip_c, material=material, name=grip_kind)
        top_r = w / 2
        if marker_kind in ("dial", "none"):
            sym = 2
    else:
        grip = Visual("mesh", file=_grip_mesh(ctx, grip_kind, rg, z_grip0, z1, drng), color=grip_c,
                      material=material, name=grip_kind)
        top_r = rg * (0.6 if grip_kind == "tapered" else 0.95)
    # the grip's top as built (a primitive's centre and size are rounded to the millimetre:
    # a marker put on the unrounded top was buried half a millimetre inside the grip on
    # some knobs, generator versions 5 and 6)
    if grip.shape == "cylinder":
        z1 = grip.pose.z + grip.length / 2
    elif grip.shape == "box":
        z1 = grip.pose.z + grip.size[2] / 2
    marker = None
    # a marker of little contrast stands proud of the grip (a raised ridge or bump: what
    # makes a dark-on-dark knob readable to a person, by its shading and its relief); one
    # that stands out in colour is printed or inlaid, half a millimetre proud
    proud = _mm(u(0.0015, 0.003)) if style in ("low-contrast", "dark-on-dark") else 0.0005
    zt = z1 + proud / 2
    if marker_kind == "line":
        if grip_kind in ("bar", "fin"):
            lw = min(w * 0.5, r * 0.12)
            marker = box(lw, rg * 0.7, proud, y=rg * 0.5, z=zt, color=mark, name="line")
        else:
            marker = box(max(0.0015, top_r * 0.14), top_r * 0.6, proud, y=top_r * 0.5, z=zt,
                         color=mark, name="line")
    elif marker_kind == "dot":
        rd = max(0.002, top_r * u(0.15, 0.25))
        marker = cyl(rd, proud, y=top_r - 1.4 * rd, z=zt, color=mark, name="dot")
    if marker_kind in ("line", "dot"):
        marker = replace(marker, pose=replace(marker.pose, z=round(zt, 5)))
    elif marker_kind == "tip":
        marker = box(w, tl, hg, y=rg - tl / 2, z=zc, color=mark, material=material, name="tip")
    elif marker_kind == "printed":
        half = max(0.001, top_r * 0.18)
        tri = [(-half, 0.0), (half, 0.0), (0.0, 0.9 * top_r if grip_kind not in ("bar", "fin") else 0.9 * rg)]
        marker = Visual("mesh", file=ctx.meshes.add("knob-printed", extrude(_ccw(tri), z1, z1 + 0.0003)),
                        color=mark, name="printed")
    out.update(base=Model(base_vis) if base_vis else None, grip=Model([grip]),
               marker=Model([marker]) if marker is not None else None,
               base_fixed=base_kind == "bezel", symmetry=sym)
    return out


def _ccw(poly):
    """The polygon's points ordered counter-clockwise about their centroid (a convex one)."""
    P = np.asarray(poly, dtype=float)
    c = P.mean(axis=0)
    order = np.argsort(np.arctan2(P[:, 1] - c[1], P[:, 0] - c[0]))
    return [tuple(P[i]) for i in order]


def _knobs(ctx: _Ctx, oid: str, count: int, place: Callable[[int], Pose],
           max_radius: float, pitch: Optional[float] = None) -> list[Knob]:
    """``count`` knobs of one design (radius at most ``max_radius``); ``place(i)`` gives the
    i-th knob's pose, ``pitch`` (m, given for a row along y) the distance between neighbours.
    The design's family (KNOB_FAMILIES), colours and proportions, and whether a row is
    packed (closed up to 2-2.2 radii apart, centred) come from ``ctx.design_rng``. Each knob has its own
    states; most are off."""
    _, body, marker, rr, dr = ctx.pick(KNOB_DESIGNS)
    r, depth = _mm(min(ctx.u(*rr), max_radius)), _mm(ctx.u(*dr))
    drng = ctx.design_rng
    design, turn_stop, packed = {}, False, None
    if drng is not None:
        turn_stop = bool(drng.random() < 0.5)
        if pitch is not None and drng.random() < 0.3:
            packed = r * float(drng.uniform(2.0, 2.2))      # the row closed up, centred
        if drng.random() >= ctx.cfg.plain_knob_probability:
            design = _knob_design(ctx, r, depth)
    design.pop("design", None)

    def pose(i: int) -> Pose:
        p = place(i)
        return p if packed is None else replace(p, y=_mm(((count - 1) / 2 - i) * packed))
    sym = design.get("symmetry", 1)
    out = []
    for i in range(count):
        states, off, explicit, direction = _knob_states(ctx, sym)
        on = ctx.chance(ctx.cfg.knob_on_probability)
        choices = [s for s in states if (s.name != off) == on] or states
        st = choices[int(ctx.rng.integers(len(choices)))]
        turns = ("clockwise" if direction < 0 else "counterclockwise") if turn_stop and direction else "either"
        out.append(Knob(f"{oid}_knob_{i + 1}", pose(i), states, st.name, angle=st.angle,
                        radius=r, depth=depth, color=body, marker_color=marker,
                        off_state=off if explicit else "", turns=turns, **design))
    return out


