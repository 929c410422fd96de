"""A runner for the suite tests: a case whose ``params`` say ``standin`` misbehaves in the
worker (raises, exits, hangs, hangs and ignores the alarm); any other runs for real."""
from __future__ import annotations

import os
import signal
import threading


def run(case, world=None):
    what = case.params.get("standin")
    if what == "raise":
        raise RuntimeError("forced crash of a stand-in scenario")
    if what == "exit":
        os._exit(3)
    if what == "hang":
        threading.Event().wait()
    if what == "stubborn":
        signal.signal(signal.SIGALRM, signal.SIG_IGN)
        threading.Event().wait()
    from hearth.executive.scenarios import run_case
    return run_case(case, world=world)
