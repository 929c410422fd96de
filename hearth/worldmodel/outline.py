"""Room floors as polygons: a room's outline, whether a floor point lies in it, how far it is
from its walls, and the rectangle of a doorway's passage (docs/world-format.md, "Rooms and
doorways").

Coordinates are (x, y) in metres in the room's frame. Plain Python over a handful of
corners: validating a file must not need numpy's start-up, and a room has tens of corners at
most (written by hand: no dependency of Hearth has 2-D polygon predicates; shapely would be
a new dependency for four functions).
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

Point = tuple[float, float]

#: Most corners a room's outline may have (the schema says the same).
MAX_OUTLINE_CORNERS = 256


def room_outline(room) -> list[Point]:
    """The room's floor polygon in its frame, counter-clockwise: its ``outline``, else the
    four corners of its ``bounds`` from (xmin, ymin); [] for a room with neither."""
    if getattr(room, "outline", None):
        poly = [(float(x), float(y)) for x, y in room.outline]
        return poly if signed_area(poly) >= 0 else poly[::-1]
    if room.bounds is None:
        return []
    x0, y0, x1, y1 = room.bounds
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def signed_area(poly: Sequence[Point]) -> float:
    """Shoelace area (m^2): positive for a counter-clockwise polygon."""
    n = len(poly)
    return 0.5 * sum(poly[i][0] * poly[(i + 1) % n][1] - poly[(i + 1) % n][0] * poly[i][1]
                     for i in range(n))


def _segment_distance(px: float, py: float, a: Point, b: Point) -> float:
    dx, dy = b[0] - a[0], b[1] - a[1]
    L2 = dx * dx + dy * dy
    t = 0.0 if L2 == 0 else max(0.0, min(1.0, ((px - a[0]) * dx + (py - a[1]) * dy) / L2))
    return math.hypot(px - a[0] - t * dx, py - a[1] - t * dy)


def outline_distance(poly: Sequence[Point], x: float, y: float) -> float:
    """Distance (m) from (x, y) to the polygon's boundary (its walls); inf for no polygon."""
    n = len(poly)
    if n == 0:
        return math.inf
    return min(_segment_distance(x, y, poly[i], poly[(i + 1) % n]) for i in range(n))


def _inside(poly: Sequence[Point], x: float, y: float) -> bool:
    """Even-odd ray casting."""
    inside = False
    n = len(poly)
    for i in range(n):
        (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % n]
        if (y0 > y) != (y1 > y):
            xc = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
            if x < xc:
                inside = not inside
    return inside


def outline_contains(poly: Sequence[Point], x: float, y: float, margin: float = 0.0) -> bool:
    """Whether (x, y) lies in the polygon grown by ``margin`` (negative: shrunk): inside and at
    least -margin from the walls, or outside and at most margin from them. For a rectangle
    this is its bounds grown by margin but for rounded corners (and a point within
    ``margin`` of a rectangle's corner diagonally is then out: the old bounds test let it
    in)."""
    if len(poly) < 3:
        return False
    if _inside(poly, x, y):
        return margin >= 0 or outline_distance(poly, x, y) >= -margin
    return margin > 0 and outline_distance(poly, x, y) <= margin


def _cross(o: Point, a: Point, b: Point) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _segments_cross(a: Point, b: Point, c: Point, d: Point) -> bool:
    d1, d2 = _cross(c, d, a), _cross(c, d, b)
    d3, d4 = _cross(a, b, c), _cross(a, b, d)
    return ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and 0 not in (d1, d2, d3, d4)


def outline_problem(poly: Sequence[Point]) -> Optional[str]:
    """Why the corners do not make a room's floor (None: they do): at least 3 corners,
    none repeated, an area, no side crossing another."""
    n = len(poly)
    if n < 3:
        return f"needs at least 3 corners, has {n}"
    if n > MAX_OUTLINE_CORNERS:
        return f"has {n} corners (at most {MAX_OUTLINE_CORNERS})"
    for i in range(n):
        if math.dist(poly[i], poly[(i + 1) % n]) < 1e-6:
            return f"repeats corner {i + 1} ({poly[i][0]:g}, {poly[i][1]:g})"
    if abs(signed_area(poly)) < 1e-6:
        return "encloses no area"
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            if _segments_cross(poly[i], poly[(i + 1) % n], poly[j], poly[(j + 1) % n]):
                return f"sides {i + 1} and {j + 1} cross"
    return None


def doorway_rect(doorway) -> list[Point]:
    """The four corners (room frame, counter-clockwise) of a doorway's passage: ``depth``
    along its +x, centred on its pose, ``width`` across."""
    p = doorway.pose
    c, s = math.cos(p.yaw), math.sin(p.yaw)
    hx, hy = doorway.depth / 2, doorway.width / 2
    return [(p.x + c * u - s * v, p.y + s * u + c * v)
            for u, v in ((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))]


def segment_clip(a: Point, b: Point, convex: Sequence[Point]) -> Optional[tuple[float, float]]:
    """The part of segment a-b inside a convex counter-clockwise polygon, as parameters
    (t0, t1) along it (0 at a, 1 at b), or None (Cyrus-Beck clipping)."""
    t0, t1 = 0.0, 1.0
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = len(convex)
    for i in range(n):
        p, q = convex[i], convex[(i + 1) % n]
        # inside: left of p->q, cross(q - p, x - p) >= 0
        ex, ey = q[0] - p[0], q[1] - p[1]
        num = ex * (a[1] - p[1]) - ey * (a[0] - p[0])
        den = ex * dy - ey * dx
        if abs(den) < 1e-12:
            if num < 0:
                return None
            continue
        t = -num / den
        if den > 0:
            t0 = max(t0, t)
        else:
            t1 = min(t1, t)
        if t0 > t1:
            return None
    return (t0, t1)


def room_openings(apartment, room) -> list[list[Point]]:
    """The passages of every doorway of the home (``apartment``: an Apartment or a World) as
    rectangles in ``room``'s frame: the walls of ``room`` are open where one crosses them
    (a doorway written in one room cuts the wall of the room it leads to as well)."""
    rooms = list(getattr(apartment, "rooms", None) or apartment.apartment.rooms)
    out = []
    cr, sr = math.cos(room.pose.yaw), math.sin(room.pose.yaw)
    for other in rooms:
        co, so = math.cos(other.pose.yaw), math.sin(other.pose.yaw)
        for d in other.doorways:
            pts = []
            for x, y in doorway_rect(d):
                wx = other.pose.x + co * x - so * y         # other room -> world -> room
                wy = other.pose.y + so * x + co * y
                ux, uy = wx - room.pose.x, wy - room.pose.y
                pts.append((cr * ux + sr * uy, -sr * ux + cr * uy))
            out.append(pts)
    return out
