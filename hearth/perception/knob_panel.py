"""Where an appliance's knobs really are: one shift of the whole knob panel, from the depth image.

The knob reader looks for each knob within a few centimetres of where the map and the robot's
pose put it (``KnobConfig`` search radius: the registration error). When the robot's pose is
off by more (a flush front that fixes nothing along it, a landmark fix a few centimetres
short), every knob region misses its knob and the mission can only say "no knob found". All
knobs of one panel are off by the same shift, though, and knobs stand out of their panel
whatever their colours, so the depth image says where the panel's knobs are as a set:

1. the knobs are grouped by their panel plane (``panel_groups``: axes parallel, planes within
   ``plane_tol``);
2. the depth image is seen through a canvas on that plane (``px_per_m``), covering the knobs
   and ``max_shift`` (20 cm) around them, as heights above the plane (the same ray geometry as
   ``hearth.perception.knobs.canvas_heights``); what stands out of the surface by less than a
   knob's width is kept (a top-hat: the panel's slope, edges and steps are taken off), so
   that the pose's error across and about the plane does not matter;
3. a template of the knobs as the map places them, seen from the camera (what of each knob
   stands whatever its angle, ``hearth.perception.knobs.standing_profile``, as discs of 0.85 of
   its radius at its height: a round knob a cylinder, a bar grip its middle on its disc;
   the panel flat around them) is slid over it (OpenCV's
   ``matchTemplate``, normalised correlation), every shift within ``max_shift``; where the
   panel stands off its believed plane (around the best match), that is matched again on
   the panel's own plane;
4. the peaks of the match (at least ``min_separation`` radii apart, the best ``max_peaks``)
   are candidates only when every knob in view stands where they put it (a bump over 0.3 of
   the knob's height on at least half of its face, each knob looked for on its own within
   ``local_reach`` radii: a turn of the pose moves the knobs at the ends of a long panel
   apart by a centimetre or two): a row matched one pitch off leaves a knob on bare panel at
   one end;
5. the best candidate is used when it scores at least ``min_score`` and leads every other
   candidate by ``min_lead`` (a row shifted by a pitch whose end knob is out of view is
   still a candidate: then nothing is moved and each knob is searched where the map says,
   as before). When that ambiguous best match moves a knob further than the reader's own
   search, which knob is which is not sure: the knobs are read both where the map puts them
   and where the match puts them, and a knob read differently the two ways is "unknown"
   (``read_panel``; home 18, a pose 9 cm off along a row of five skirt knobs 12.6 cm apart:
   each region held its neighbour, an "on" knob was read "off" from its neighbour's dot and
   the mission ended in a wrong success).

The knobs are then read where the panel is (``shift_priors``). Only the knobs' image
positions change, not the map or the robot's pose. Written here because no library matches a
set of protrusions on a plane seen in perspective; the matching itself is OpenCV's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Optional, Sequence

import cv2
import numpy as np

from hearth.perception.camera import Intrinsics
from hearth.perception.knob_canvas import plane_heights


@dataclass(frozen=True)
class PanelConfig:
    """``max_shift``: the largest shift searched (m); ``px_per_m``: the canvas scale;
    ``min_score``: the normalised correlation a match needs; ``local_reach``: how far (radii)
    each knob is then looked for on its own around where the panel's match puts it, and
    ``local_score``: the correlation its own match needs to move it, ``local_min``: the least
    shift of its own that is used (m; less is left to the reader's search); ``min_lead``: how much better
    than any other peak ``min_separation`` radii away it must be; ``min_shift``: a shift below
    it (m) is left alone (the per-knob search covers it); ``min_valid``: the share of the canvas that needs a
    depth reading."""
    max_shift: float = 0.2
    px_per_m: float = 400.0
    min_score: float = 0.45
    min_lead: float = 0.08
    min_separation: float = 0.7
    min_shift: float = 0.004
    max_peaks: int = 8
    local_reach: float = 0.6
    local_score: float = 0.5
    local_min: float = 0.008
    min_valid: float = 0.3
    plane_tol: float = 0.01


#: ``PanelFix.why`` of a panel found where the map puts it (nothing to move, nothing to say).
WHERE_THE_MAP_SAYS = "where the map says"


@dataclass(frozen=True)
class PanelFix:
    """The shift (m, world frame) of a group of knobs, its size (m), the match's score and its
    lead over the next other peak; ``used``: whether it passed the gates; ``knobs``: each
    knob's own shift (the panel's and its own around it, m, world frame); ``here_ok``: whether
    every knob in view stands on a bump where the map puts it; ``ambiguous``: another match
    came within ``min_lead`` of this one."""
    knob_ids: tuple[str, ...]
    shift_world: np.ndarray
    shift_m: float
    score: float
    lead: float
    used: bool
    why: str = ""
    knobs: dict = field(default_factory=dict)
    here_ok: bool = False
    ambiguous: bool = False


def _shifted(prior, shift_world: np.ndarray):
    """The knob prior moved by ``shift_world`` (m, world frame)."""
    T = prior.T_world_knob.copy()
    T[:3, 3] = T[:3, 3] + shift_world
    return replace(prior, T_world_knob=T)


def panel_groups(priors: Sequence, tol: float = 0.01) -> list[list]:
    """The priors grouped by panel: knob axes parallel (within about 3 degrees) and their
    planes (z = 0 of the knob frames) within ``tol`` of each other."""
    groups: list[list] = []
    for p in priors:
        T = p.T_world_knob
        for g in groups:
            R = g[0].T_world_knob
            if float(T[:3, 2] @ R[:3, 2]) > 0.9985 and abs(float(R[:3, 2] @ (T[:3, 3] - R[:3, 3]))) < tol:
                g.append(p)
                break
        else:
            groups.append([p])
    return groups


def _canvas_homography(K: Intrinsics, T_wc: np.ndarray, T_wp: np.ndarray, ppm: float,
                       x0: float, y1: float) -> np.ndarray:
    """Canvas pixel (j, i) -> image pixel: the canvas shows plane z = 0 of ``T_wp`` head-on at
    ``ppm``, pixel (0, 0) at plane point (x0, y1), right = +x, down = -y."""
    T_cp = np.linalg.inv(T_wc) @ T_wp
    H = K.matrix() @ np.column_stack([T_cp[:3, 0], T_cp[:3, 1], T_cp[:3, 3]])
    return H @ np.array([[1.0 / ppm, 0.0, x0], [0.0, -1.0 / ppm, y1], [0.0, 0.0, 1.0]])


def _heights(depth: np.ndarray, H: np.ndarray, w: int, h: int, cam_height: float):
    """Heights (m) above the plane of what the depth image shows through each canvas pixel,
    and where there is a reading within 15 cm of the plane (``hearth.perception.knobs.plane_heights``)."""
    hh, seen = plane_heights(depth, H, w, h, cam_height)
    valid = seen & (np.abs(hh) < 0.15)
    return np.where(valid, hh, 0.0), valid


def _bumps(hh: np.ndarray, valid: np.ndarray, radius_px: float) -> np.ndarray:
    """What stands out of the surface by less than a knob's width: the heights less their
    morphological opening with a disc a little wider than a knob (OpenCV's top-hat), so that
    the panel's slope, its edges and steps (a door standing out below it, a hob above) are
    taken off and the knobs are left. Pixels without a reading take the median height; a 5 px
    median filter first takes off the sensor's speckle."""
    fill = float(np.median(hh[valid])) if valid.any() else 0.0
    h = cv2.medianBlur(np.where(valid, hh, fill).astype(np.float32), 5)   # the sensor's speckle
    k = 2 * int(math.ceil(1.3 * radius_px)) + 1
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    return cv2.morphologyEx(h, cv2.MORPH_TOPHAT, disc)


def _match(depth, K: Intrinsics, T_wc: np.ndarray, ref: np.ndarray, priors: Sequence,
           cfg: PanelConfig):
    """One pass on the plane z = 0 of ``ref``: (score, lead, shift x, shift y in the plane,
    the panel's median height above the plane where the knobs matched, how many knobs in
    view have no bump where the match puts them); None when the panel is not in view or too
    little of it has a depth reading."""
    inv = np.linalg.inv(ref)
    xy = np.array([(inv @ p.T_world_knob[:, 3])[:2] for p in priors])
    rmax = max(p.radius for p in priors)
    rmin = min(p.radius for p in priors)
    ppm = cfg.px_per_m
    pad_t = 1.2 * rmax                                      # flat panel around the knobs
    lo, hi = xy.min(axis=0) - pad_t, xy.max(axis=0) + pad_t
    tw, th = int(math.ceil((hi[0] - lo[0]) * ppm)), int(math.ceil((hi[1] - lo[1]) * ppm))
    off = int(math.ceil(cfg.max_shift * ppm))
    w, h = tw + 2 * off, th + 2 * off
    x0, y1 = lo[0] - off / ppm, hi[1] + off / ppm
    H = _canvas_homography(K, T_wc, ref, ppm, x0, y1)
    cam = inv @ T_wc[:, 3]
    cam_h = float(cam[2])
    if cam_h <= 0:
        return None                                         # the camera is behind the panel
    hh, valid = _heights(depth, H, w, h, cam_h)
    if valid[off:off + th, off:off + tw].mean() < cfg.min_valid:
        return None
    dmax = max(p.depth for p in priors)
    measured = np.clip(_bumps(hh, valid, rmax * ppm), 0.0, 1.2 * dmax).astype(np.float32)
    tpl = np.zeros((th, tw), np.float32)
    tj, ti = np.meshgrid((np.arange(tw) + 0.5) / ppm + lo[0], hi[1] - (np.arange(th) + 0.5) / ppm)
    tops, foots = {}, {}                    # each knob's face and all of it, as the camera sees them
    top_h = {}
    for (x, y), p in zip(xy, priors):
        # what of the knob stands whatever its angle (``standing_profile``: a round cap all
        # of it, a bar grip only its middle, a bezel its disc; a cylinder of the outline
        # when the prior has no profile), seen from the camera: the section at height z lands
        # on the plane pushed away from the camera's foot by z / (h - z) of its distance and
        # magnified as much; the canvas shows the height of the highest section over each point
        prof = [(0.85 * min(r, p.radius), zt) for r, zt in getattr(p, "profile", ()) if r > 0] \
            or [(0.85 * p.radius, p.depth)]
        z_top = max(zt for _r, zt in prof)
        for z in np.linspace(0.0, z_top, 6):
            rad = max((r for r, zt in prof if zt >= z - 1e-9), default=0.0)
            if rad <= 0:
                continue
            g = z / max(cam_h - z, 1e-3)
            cx, cy = x + g * (x - cam[0]), y + g * (y - cam[1])
            # at least a canvas pixel across (a thin fin's middle is narrower than one)
            disc = (tj - cx) ** 2 + (ti - cy) ** 2 <= (max(rad, 1.0 / ppm) * (1 + g)) ** 2
            tpl[disc] = np.maximum(tpl[disc], z)
            foots[p.knob_id] = disc | foots.get(p.knob_id, False)
        # the face a bump must show: the widest part standing at least half the top's height
        r_top, h_top = max(((r, zt) for r, zt in prof if zt >= 0.5 * z_top), key=lambda q: q[0])
        g = h_top / max(cam_h - h_top, 1e-3)
        top_h[p.knob_id] = h_top
        tops[p.knob_id] = ((tj - x - g * (x - cam[0])) ** 2 + (ti - y - g * (y - cam[1])) ** 2
                           <= (max(min(0.6 * p.radius, r_top / 0.85 * 0.7), 1.5 / ppm) * (1 + g)) ** 2)
    S = np.nan_to_num(cv2.matchTemplate(measured, tpl, cv2.TM_CCOEFF_NORMED), nan=-1.0)
    dy, dx = np.mgrid[0:S.shape[0], 0:S.shape[1]]
    sx, sy = (dx - off) / ppm, -(dy - off) / ppm
    inside = np.hypot(sx, sy) <= cfg.max_shift
    S = np.where(inside, S, -1.0)
    reach = int(round(cfg.local_reach * rmin * ppm))

    def knobs_at(r: int, c: int):
        """Each knob on its own, within ``local_reach`` radii of where the panel's match at
        (r, c) puts it (a turn of the pose moves the knobs of a long panel apart, by a
        centimetre or two at its ends): its own part of the template matched around there;
        and how many knobs in view have no bump there: every knob of the panel that is in
        view must stand where the match puts it (a row matched one pitch off leaves a knob
        on bare panel at one end, a match on a handle or another appliance knobs in the air)."""
        local, missing = {}, 0
        for p in priors:
            top = tops[p.knob_id]
            ii_, jj_ = np.nonzero(foots[p.knob_id])
            i0, i1, j0, j1 = ii_.min(), ii_.max() + 1, jj_.min(), jj_.max() + 1
            r0, c0 = r + i0 - reach, c + j0 - reach
            region = measured[max(r0, 0):r + i1 + reach, max(c0, 0):c + j1 + reach]
            u = v = 0
            if r0 >= 0 and c0 >= 0 and region.shape == (i1 - i0 + 2 * reach, j1 - j0 + 2 * reach):
                Sk = np.nan_to_num(cv2.matchTemplate(region, tpl[i0:i1, j0:j1], cv2.TM_CCOEFF_NORMED),
                                   nan=-1.0)
                q = np.unravel_index(int(np.argmax(Sk)), Sk.shape)
                if Sk[q] >= cfg.local_score:
                    v, u = int(q[0]) - reach, int(q[1]) - reach
            # (a shift the reader's own search covers is left to it: the match is to a pixel)
            local[p.knob_id] = (u / ppm, -v / ppm) if math.hypot(u, v) / ppm >= cfg.local_min else (0.0, 0.0)
            rows, cols = r + v, c + u
            if rows < 0 or cols < 0 or rows + th > h or cols + tw > w:
                continue
            window = measured[rows:rows + th, cols:cols + tw]
            seen = valid[rows:rows + th, cols:cols + tw]
            if not top.any() or seen[top].mean() < 0.5:
                # out of view or no reading (or a face too small for the canvas' pixels)
                continue
            missing += float((window[top & seen] > 0.3 * top_h[p.knob_id]).mean()) < 0.5
        return local, missing

    # the peaks of the match, best first, at least ``min_separation`` radii apart; a peak that
    # leaves a knob in view on bare panel is no candidate (nor a rival of the best)
    sep = max(1, int(round(cfg.min_separation * rmin * ppm)))
    peak = (S >= cv2.dilate(S, np.ones((2 * sep + 1, 2 * sep + 1), np.uint8)) - 1e-7) & inside & (S > -0.5)
    order = np.argsort(-S[peak])
    cand = []
    for r, c in np.argwhere(peak)[order]:
        if all(math.hypot(r - a, c - b) > sep for a, b, *_ in cand):
            cand.append((int(r), int(c)) + knobs_at(int(r), int(c)))
        if len(cand) >= cfg.max_peaks:
            break
    if not cand:
        return None
    fit = [q for q in cand if q[3] == 0]
    r, c, local, missing = fit[0] if fit else cand[0]
    k = (r, c)
    best = float(S[k])
    bx, by = float(sx[k]), float(sy[k])
    second = max([float(S[a, b]) for a, b, _, m in fit if (a, b) != k] + [-1.0])
    # the knobs where the map puts them: do they stand on bumps? (a shift is then weighed
    # against reading them there: ``read_panel``)
    here_ok = knobs_at(off, off)[1] == 0 if 0 <= off < S.shape[0] and off < S.shape[1] else False
    at = (slice(r, r + th), slice(c, c + tw))
    foot = valid[at] & (tpl == 0) & (measured[at] < 0.003)
    lift = float(np.median(hh[at][foot])) if foot.sum() > 20 else 0.0
    return best, best - second, bx, by, lift, missing, local, here_ok


def locate_panel(depth: np.ndarray, K: Intrinsics, T_wc: np.ndarray, priors: Sequence,
                 cfg: PanelConfig = PanelConfig()) -> Optional[PanelFix]:
    """The shift of one panel's knobs (``priors``, one ``panel_groups`` group) that the depth
    image shows (module docstring); None when the panel is not in view or too little of it has
    a depth reading. When the panel stands off its believed plane (the pose's error along the
    knobs' axis), what the plane shows is matched again on the panel's own plane: an oblique
    view puts a knob off its believed plane elsewhere on that plane."""
    if depth is None or not priors:
        return None
    ref = priors[0].T_world_knob.copy()
    m = _match(depth, K, T_wc, ref, priors, cfg)
    if m is None:
        return None
    lift, here_ok = 0.0, m[7]
    if m[0] >= cfg.min_score and abs(m[4]) > 0.003:
        lift = m[4]
        ref2 = ref.copy()
        ref2[:3, 3] += ref[:3, 2] * lift
        moved = [_shifted(p, ref[:3, 2] * lift) for p in priors]
        m2 = _match(depth, K, T_wc, ref2, moved, cfg)
        if m2 is not None:
            m = m2
    best, lead, bx, by, _, missing, local, _ = m
    shift = ref[:3, 0] * bx + ref[:3, 1] * by + ref[:3, 2] * lift
    knobs = {kid: shift + ref[:3, 0] * lx + ref[:3, 1] * ly for kid, (lx, ly) in local.items()}
    size = float(np.linalg.norm(shift))
    ids = tuple(p.knob_id for p in priors)
    if best < cfg.min_score:
        return PanelFix(ids, shift, size, best, lead, False, knobs=knobs, here_ok=here_ok, why=f"no match (score {best:.2f})")
    if missing:
        many = missing != 1
        return PanelFix(ids, shift, size, best, lead, False, knobs=knobs, here_ok=here_ok,
                        why=f"{missing} knob{'s' if many else ''} not where the match puts "
                            f"{'them' if many else 'it'}")
    if lead < cfg.min_lead:
        return PanelFix(ids, shift, size, best, lead, False, knobs=knobs, here_ok=here_ok,
                        why=f"ambiguous (lead {lead:.2f})", ambiguous=True)
    if max([size] + [float(np.linalg.norm(v)) for v in knobs.values()]) < cfg.min_shift:
        return PanelFix(ids, shift, size, best, lead, False, knobs=knobs, here_ok=here_ok,
                        why=WHERE_THE_MAP_SAYS)
    return PanelFix(ids, shift, size, best, lead, True, knobs=knobs, here_ok=here_ok)


def shift_priors(priors: Sequence, depth: Optional[np.ndarray], K: Intrinsics, T_wc: np.ndarray,
                 cfg: PanelConfig = PanelConfig()) -> tuple[list, list[PanelFix]]:
    """The priors with each panel's knobs moved by the shift its depth image shows (when
    ``locate_panel`` found one it trusts), and what was found per panel."""
    out, fixes = {p.knob_id: p for p in priors}, []
    if depth is None:
        return list(priors), fixes
    for group in panel_groups(priors, cfg.plane_tol):
        fix = locate_panel(depth, K, T_wc, group, cfg)
        if fix is None:
            continue
        fixes.append(fix)
        if fix.used:
            for p in group:
                out[p.knob_id] = _shifted(p, fix.knobs.get(p.knob_id, fix.shift_world))
    return [out[p.knob_id] for p in priors], fixes


def read_panel(reader, rgb: np.ndarray, K: Intrinsics, T_wc: np.ndarray, priors: Sequence,
               depth: Optional[np.ndarray] = None, only: Optional[set] = None,
               cfg: PanelConfig = PanelConfig()) -> tuple[list, list[PanelFix]]:
    """Read the knobs of ``priors`` (``only``: the ids to read; the panel is found with all of
    them) with ``reader`` (a ``KnobReader``) where the depth image shows their panel, when the
    reader agrees: a match that moves no knob further than the reader's own search radius is
    taken; otherwise the knobs are read where the map puts them and where the match puts
    them, and the match is taken when the reader finds more knobs there, or as many when the
    map's places are not all on bumps (a row one pitch off: its regions hold the neighbours).
    A panel whose match is not taken gets ``used`` False and the reason. A panel whose best
    match is ambiguous and moves a knob beyond the reader's search (a row one pitch along
    matches as well) is read both ways, and its knobs read differently are "unknown"
    (``_same_both_ways``). Returns the readings and what was found per panel
    (``shift_priors``)."""
    moved, fixes = shift_priors(priors, depth, K, T_wc, cfg)
    keep = lambda ps: [p for p in ps if only is None or p.knob_id in only]
    used = [f for f in fixes if f.used]
    rc = reader.config
    reach = {p.knob_id: max(rc.search_m, rc.search_radii * p.radius) for p in priors}
    if not used:
        here = reader.read(rgb, K, T_wc, keep(priors), depth=depth)
        doubtful = [f for f in fixes if f.ambiguous and any(
            float(np.linalg.norm(v)) > reach[k] for k, v in f.knobs.items())]
        if doubtful:
            here = _same_both_ways(reader, rgb, K, T_wc, keep(priors), here, doubtful, depth)
        return here, fixes
    near = all(float(np.linalg.norm(v)) <= reach[k] for f in used for k, v in f.knobs.items())
    if near:
        # within the reader's own search radius (0.6 radii or 14 mm) of where the map puts
        # them, a region still cannot reach a neighbour (2 radii away at least), and the
        # reader starts nearer
        return reader.read(rgb, K, T_wc, keep(moved), depth=depth), fixes
    here = reader.read(rgb, K, T_wc, keep(priors), depth=depth)
    there = reader.read(rgb, K, T_wc, keep(moved), depth=depth)
    n_here, n_there = sum(r.found for r in here), sum(r.found for r in there)
    if n_there > n_here or (n_there == n_here > 0 and not all(f.here_ok for f in used)):
        return there, fixes
    why = (f"its knobs are found where the map puts them ({n_here} of {len(here)}; "
           f"{n_there} where the match puts them)")
    return here, [replace(f, used=False, why=why) if f.used else f for f in fixes]


def _same_both_ways(reader, rgb: np.ndarray, K: Intrinsics, T_wc: np.ndarray, priors: Sequence,
                    here: list, doubtful: Sequence[PanelFix], depth: Optional[np.ndarray]) -> list:
    """``here`` (the readings of ``priors`` where the map puts them) with every knob of the
    ``doubtful`` panels that reads otherwise where their ambiguous match puts it made
    "unknown": with the robot's pose a knob pitch off, each region holds its neighbour, and
    its reading is the neighbour's state (an "on" knob read "off"). A knob that reads the
    same both ways (or is unknown here) keeps its reading, and so do the knobs of a panel
    none of whose knobs the reader finds where the match puts them: the reader refutes that
    match (home 2, the pose right, matches 8-16 cm along over bare panel)."""
    shift = {k: v for f in doubtful for k, v in f.knobs.items()}
    there = {}
    moved = [_shifted(p, shift[p.knob_id]) for p in priors if p.knob_id in shift]
    if moved:
        there = {r.knob_id: r for r in reader.read(rgb, K, T_wc, moved, depth=depth)}
    for f in doubtful:
        if not any(there[k].found for k in f.knob_ids if k in there):
            there = {k: r for k, r in there.items() if k not in f.knob_ids}
    out = []
    for r in here:
        t = there.get(r.knob_id)
        told = r.state != "unknown" or r.evidence.get("off_one_view")
        if t is None or not told or (t.state == r.state and bool(t.evidence.get("off_one_view"))
                                     == bool(r.evidence.get("off_one_view"))):
            out.append(r)
            continue
        f = next(f for f in doubtful if r.knob_id in f.knobs)
        other = t.state if t.found else "no knob"
        lean = r.state if r.state != "unknown" else r.evidence.get("leaning", "unknown")
        ev = {k: v for k, v in r.evidence.items() if k != "off_one_view"}
        out.append(replace(r, state="unknown", confidence=0.0, evidence=ev,
                           reason=f"unsure ({lean}: its panel matches as well "
                                  f"{f.shift_m * 100:.0f} cm along, where it reads {other})"))
    return out
