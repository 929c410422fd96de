"""`hearth demo`: the three named missions on the simulated demo home (what `make demo` runs).

Run refine_localisation, turn_off_oven and fetch_object on the simulated demo home with a
perturbed truth (the blue cup moved to the side table, an oven knob on, localisation about
10 cm off); print progress and a report; write the execution logs and a top-down PNG.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

from hearth.cli.util import add_command, output_dir, seed
from hearth import demo_world_path, missions_dir

DEMO_WORLD = demo_world_path()
MISSIONS = missions_dir()

#: (mission file, parameters, what it is for)
DEMO_MISSIONS = (
    ("refine_localisation.yaml", {"at": "cupboard"}, "correct the drifted localisation"),
    ("turn_off_oven.yaml", {}, "turn off the knob left on"),
    ("fetch_object.yaml", {"object": "blue cup", "bring_to": "kitchen_table"},
     "bring the blue cup (it is not where the map says)"),
)


#: Map updates that say where an object was seen (not HandOver, which puts it down).
FOUND_BY = ("UpdateObjectLocation", "DetectObject")

def register(sub) -> None:
    p = add_command(sub, "demo", __doc__,
                    help="run the three named missions on the simulated demo home")
    p.add_argument("--world", default=str(DEMO_WORLD), help="world file (default: the demo home)")
    p.add_argument("--out", type=output_dir, default="out/demo",
                   help="output directory (default out/demo)")
    p.add_argument("--seed", type=seed, default=0, help="sensor noise seed")
    p.add_argument("--quiet", action="store_true", help="print only the report")
    p.set_defaults(func=_run)


def perturbed_truth(world, seed: int = 0):
    """The demo's truth: a copy of ``world`` with the blue cup on the side table and oven knob
    2 on; and the localisation error (body frame, ~10 cm, 2 degrees)."""
    import numpy as np

    from hearth.executive.scenarios import place_on
    from hearth.worldmodel.pose import Pose
    truth = world.copy()
    if "blue_cup" in truth and "side_table" in truth:
        place_on(truth, "blue_cup", "side_table", np.random.default_rng(seed), source="demo")
    if "oven_knob_2" in truth:
        k = truth.get("oven_knob_2")
        on = [s.name for s in k.states if s.name != k.off]
        truth.set_knob_state(k.id, on[min(1, len(on) - 1)], source="demo")
    return truth, Pose.planar(0.08, -0.06, math.radians(2.0))


class _Progress:
    """Prints a mission's progress: run states, each skill's final word, what was said.

    Which nodes are skills comes from the mission (:meth:`follow`), whether a skill is still
    running from its status events: a running action reports its progress every tick, so a
    skill's feedback is printed only once it has finished."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.skills: set[str] = set()      # tree paths of the followed mission's skills
        self.running: set[str] = set()     # of those, the ones running now
        self.last: dict[str, str] = {}
        self.previous = ""

    def follow(self, mission) -> None:
        self.skills = {n.path for n in mission.nodes() if n.kind == "skill"}
        self.running.clear()

    def __call__(self, e) -> None:
        from hearth.executive.events import EventKind, RunState
        if self.quiet:
            return
        if e.kind is EventKind.RUN:
            state = e.data.get("state")
            print(f"  [{e.time:7.1f} s] mission {state}"
                  + (f": {e.data.get('reason')}" if state != RunState.RUNNING else ""))
        elif e.kind is EventKind.STATUS and e.path in self.skills:
            if e.data.get("status") == "RUNNING":
                self.running.add(e.path)
            else:
                self.running.discard(e.path)
        elif e.kind is EventKind.FEEDBACK and e.path in self.skills:
            msg = str(e.data.get("message", ""))
            if (e.path in self.running or not msg or msg == self.previous
                    or msg == self.last.get(e.path)):
                return
            self.last[e.path] = self.previous = msg
            print(f"  [{e.time:7.1f} s] {e.path.rsplit('/', 1)[-1]}: {msg}")


def _run(args) -> int:
    from hearth.executive.executive import Executive
    from hearth.robot.clock import SimClock
    from hearth.robot.simulated import SimulatedRobot
    from hearth.worldmodel.io import load_world
    from hearth.worldmodel.topdown import Overlay, draw, save_png

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    clock = SimClock()
    belief = load_world(args.world, clock=clock)
    truth, error = perturbed_truth(belief, args.seed)
    robot = SimulatedRobot(truth, clock=clock, localisation_error=error, seed=args.seed)
    print(f"Hearth demo on {args.world}: {len(belief.ids())} nodes in {len(belief.rooms)} rooms")
    print("The truth differs from the map: the blue cup is on the side table, oven knob 2 is "
          f"on, and the robot believes it is {math.hypot(error.x, error.y) * 100:.0f} cm and "
          f"{math.degrees(error.yaw):.0f} degrees from where it is.")
    print("(First run: the knob and segmentation models are trained and cached; this takes a "
          "few minutes once.)\n")

    path: list[tuple[float, float]] = []
    visited: list[tuple[float, float, float]] = []
    history_start = len(belief.history())

    def track(e) -> None:
        p = robot.true_pose()
        if not path or math.hypot(p.x - path[-1][0], p.y - path[-1][1]) > 0.02:
            path.append((p.x, p.y))

    navigate = robot.navigate_to

    def navigate_to(pose):
        # Every goal the robot is sent to (believed frame), for the picture.
        from hearth.robot.adapter import as_base_pose
        g = as_base_pose(pose)
        visited.append((g.x, g.y, g.yaw))
        return navigate(pose)
    robot.navigate_to = navigate_to

    ex = Executive(world=belief, robot=robot, clock=clock, tick_hz=10.0,
                   runs_dir=str(out / "runs"), background=False)
    ex.subscribe(track)
    progress = _Progress(args.quiet)
    ex.subscribe(progress)
    # Where each object was found, taken when the map learns it: a fetch then carries the
    # object to the user, and the map's final pose is the hand-over place.
    found: dict[str, tuple[float, float]] = {}

    def where_found(change) -> None:
        if change.source in FOUND_BY and change.node in belief:
            p = belief.T_world(change.node)[:2, 3]
            found[belief.label(change.node)] = (float(p[0]), float(p[1]))
    belief.subscribe(where_found)

    rows = []
    for file, params, why in DEMO_MISSIONS:
        t_sim, t_wall = clock.now(), time.perf_counter()
        err_before = robot.localisation_error()
        print(f"== {file[:-5]} ({why})")
        handle = ex.submit(str(MISSIONS / file), **params)
        progress.follow(handle.mission)
        ex.run_until_idle(200_000)
        r = handle.result
        err_after = robot.localisation_error()
        rows.append(dict(mission=file[:-5], outcome=r.outcome, reason=r.reason,
                         sim=clock.now() - t_sim, wall=time.perf_counter() - t_wall,
                         log=r.log_path,
                         loc=(math.hypot(err_before.x, err_before.y),
                              math.hypot(err_after.x, err_after.y))))
        print()

    # What changed in the map.
    changes = belief.history()[history_start:]
    stats = {s.object: {} for s in belief.apartment.search_stats}
    for s in belief.apartment.search_stats:
        stats[s.object][s.place] = f"{s.found}/{s.searched}"

    print("== Report")
    print(f"{'mission':<22}{'outcome':<11}{'sim s':>8}{'wall s':>8}  reason")
    for r in rows:
        print(f"{r['mission']:<22}{r['outcome']:<11}{r['sim']:>8.1f}{r['wall']:>8.1f}  "
              f"{r['reason']}")
    loc0, loc1 = rows[0]["loc"]
    print(f"\nLocalisation error (truth): {loc0 * 100:.1f} cm before, "
          f"{robot.localisation_error().x * 100:+.1f}/{robot.localisation_error().y * 100:+.1f} cm "
          f"(x/y) at the end")
    print("What changed in the map:")
    seen = set()
    for h in changes:
        if h.field in ("knob.angle", "joint.state") and h.source in ("ReadKnobs", "RegisterArticulated"):
            continue        # readings that only refine angles; states are listed
        key = (h.node, h.field, h.new)
        if key in seen:
            continue
        seen.add(key)
        print(f"  {h.node}: {h.field} {h.old} -> {h.new}  ({h.source})")
    for obj, places in stats.items():
        print(f"  search statistics for {obj} (found/searched): "
              + ", ".join(f"{p} {v}" for p, v in places.items()))
    img = draw(belief, Overlay(path=path, visited=visited, found=found,
                               title="Hearth demo: robot path (blue), poses driven to "
                                     "(orange), objects found (green)"))
    png = save_png(out / "topdown.png", img)
    print(f"\nExecution logs: {out / 'runs'}/ ({', '.join(Path(r['log']).name for r in rows if r['log'])})")
    print(f"Top-down picture: {png}")
    return 0 if all(r["outcome"] == "succeeded" for r in rows) else 1
