"""`hearth step MISSION [--param k=v] [--ticks N]`: tick a mission by hand.

Interactive commands: ``t [N]`` tick (N times), ``u NAME`` tick until the node NAME (a
name or tree path) runs or finishes, ``s NAME=VALUE`` set a runtime parameter (the next tick
sees it; a watch on it restarts its branch), ``p`` print the tree with statuses, ``b`` print
the blackboard, ``c`` continue to the end, ``q`` cancel and quit. When the mission ends the
prompt stays, to look at the tree and blackboard, until ``q`` (or end of input). With
``--ticks N`` it ticks N times, printing events, then prints the tree and blackboard. The
belief map is kept on disk as `hearth run` keeps it (--map-out, --no-save).
"""
from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from hearth.cli.util import (add_command, add_run_arguments, add_topics_argument, integer_in,
                               make_executive)

if TYPE_CHECKING:
    from hearth.executive.executive import Executive

HELP = ("t [N]: tick N times | u NAME: tick until NAME runs | s NAME=VALUE: set a runtime "
        "parameter | p: tree | b: blackboard | c: continue to the end | q: cancel and quit | "
        "h: help")


def register(sub) -> None:
    p = add_command(sub, "step", __doc__, help="step a mission tick by tick")
    add_run_arguments(p)
    add_topics_argument(p)
    p.add_argument("--ticks", type=integer_in(0, 10**9, "--ticks"), default=None,
                   help="tick N times without asking, then print tree and blackboard")
    p.set_defaults(func=_run)


class Stepper:
    """Ticks one mission on a non-background Executive; remembers statuses for printing."""

    def __init__(self, ex: Executive, handle, out=None):
        self.ex = ex
        self.handle = handle
        self.out = out if out is not None else sys.stdout
        self.statuses: dict[str, str] = {}
        self.feedback: dict[str, str] = {}
        self.blackboard: dict = {}
        handle.subscribe(self._on_event)

    def _on_event(self, e) -> None:
        from hearth.executive.events import EventKind
        from hearth.executive.replay import format_event
        if e.kind is EventKind.STATUS:
            self.statuses[e.path] = e.data["status"]
        elif e.kind is EventKind.FEEDBACK:
            self.feedback[e.path] = e.data["message"]
        if e.kind is not EventKind.TICK:
            print(format_event(e.to_json()), file=self.out)

    def tick(self, n: int = 1) -> int:
        done = 0
        while done < n and not self.handle.done:
            self.ex.tick()
            done += 1
            tree = self.ex.current_tree
            if tree is not None:
                self.blackboard = tree.blackboard()
        return done

    def run_to_end(self) -> None:
        """Tick until the mission ends (at the tick rate on a wall clock), keeping the
        blackboard to look at afterwards."""
        wall = not getattr(self.ex.clock, "simulated", False)
        while not self.handle.done:
            self.tick()
            if wall and not self.handle.done:
                self.ex.clock.sleep(self.ex.period)

    def until(self, name: str, limit: int = 100_000) -> bool:
        targets = [n.path for n in self.handle.mission.nodes()
                   if n.path == name or n.name == name or n.path.endswith("/" + name)]
        if not targets:
            print(f"no node named {name!r}", file=self.out)
            return False
        for _ in range(limit):
            if self.handle.done:
                return False
            self.tick()
            if any(self.statuses.get(t, "INVALID") != "INVALID" for t in targets):
                return True
        return False

    def tree(self) -> str:
        from hearth.executive.render import ascii_tree
        return ascii_tree(self.handle.mission.root, self.statuses, self.feedback)


def set_parameter(ex: Executive, mission, text: str) -> str:
    """``NAME=VALUE`` for a runtime parameter of ``mission``, read per its declared type and
    set on the executive; what to print (the change, or why not)."""
    from hearth.executive.errors import MissionError
    from hearth.executive.missionfile_types import parse_param_text
    name, sep, value = text.partition("=")
    name = name.strip()
    runtime = mission.runtime_parameters()
    if not sep or name not in runtime:
        known = ", ".join(runtime) or "none"
        return f"s NAME=VALUE sets a runtime parameter of {mission.name} (runtime: {known})"
    try:
        typed = parse_param_text(name, mission.parameters[name].type, value.strip())
        ex.set_parameter(name, typed)
    except MissionError as err:
        return str(err)
    return f"${name} = {typed!r} from the next tick"


def _run(args) -> int:
    from hearth.cli.util import close_map

    mission, params, ex, keeper = make_executive(args)
    try:
        return _step(args, mission, params, ex)
    finally:
        close_map(keeper)


def _step(args, mission, params, ex) -> int:
    from hearth.executive.render import blackboard_text

    handle = ex.submit(mission, **params)
    st = Stepper(ex, handle)
    if args.ticks is not None:
        st.tick(args.ticks)
        print(st.tree())
        print(blackboard_text(st.blackboard))
        print(f"status: {handle.status}")
        if not handle.done:
            handle.cancel("step finished")
            ex.run_until_idle(100_000)
        return 0
    print(HELP)
    reported = False
    while True:
        if handle.done and not reported:
            reported = True
            print(st.tree())
            print(f"{mission.name}: {handle.result.outcome} ({handle.result.reason}); "
                  f"p: tree, b: blackboard, q: quit")
        try:
            line = input(f"[{'ended' if handle.done else f'tick {ex.current_tick or 0}'}] > ").strip()
        except EOFError:
            line = "q"
        cmd, _, arg = line.partition(" ")
        if cmd == "q":
            if not handle.done:
                handle.cancel("quit from hearth step")
                ex.run_until_idle(100_000)
                print(f"{mission.name}: {handle.result.outcome} ({handle.result.reason})")
            break
        if cmd == "p":
            print(st.tree())
        elif cmd == "b":
            print(blackboard_text(st.blackboard))
        elif cmd in ("", "t", "u", "c", "s") and handle.done:
            print(f"the mission has ended ({handle.result.outcome}); p: tree, b: blackboard, "
                  f"q: quit")
        elif cmd in ("", "t"):
            st.tick(int(arg) if arg.strip().isdigit() else 1)
        elif cmd == "u" and arg:
            st.until(arg.strip())
        elif cmd == "c":
            st.run_to_end()
        elif cmd == "s":
            print(set_parameter(ex, mission, arg))
        else:
            print(HELP)
    return 0 if handle.result.outcome == "succeeded" else 1
