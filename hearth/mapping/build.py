"""`hearth map build`: named stages run in order over one recording, each writing its output
under the build directory so that one stage can be rerun (and inspected) alone, in the shape
of Open3D's reconstruction system.

- ``Stage(name, run, summary)``: ``run(ctx) -> dict`` reads what earlier stages wrote (through
  ``ctx``) and writes its own files under ``ctx.out``; the dict it returns (counts, figures)
  goes into ``build.json``. A stage raising ``StageFailed`` (or a ``PerceptionError``) is a
  partial failure: it is reported, the later stages still run on what there is, and the
  command exits 1. Bad input (``MappingError``, ``RobotError``) stops the build: one line,
  exit status 2.
- ``STAGES``: the stages in order. Other modules add theirs with ``register_stage`` (e.g. the
  semantic draft after the metric map); ``STAGE_MODULES`` lists the modules imported to
  register them.
- ``build(recording, out, config, stages=None, progress=print)``: runs the stages (all, or
  the named ones) and writes ``build.json`` (stage timings, their dicts, warnings, failures).
"""
from __future__ import annotations

import importlib
import json
import math
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Optional

from hearth.mapping import MappingError

#: Modules whose import registers stages (in order), after the metric map's.
STAGE_MODULES: list[str] = ["hearth.mapping.metric", "hearth.mapping.draft"]


class StageFailed(Exception):
    """A stage found too little in the data to produce its output (said in one line)."""


@dataclass
class Stage:
    name: str
    run: Callable[["BuildContext"], dict]
    summary: str = ""
    #: earlier stages whose outputs it reads
    needs: tuple[str, ...] = ()


STAGES: list[Stage] = []


def register_stage(stage: Stage, after: Optional[str] = None) -> None:
    """Add ``stage`` (replacing one of the same name) at the end, or right after ``after``."""
    for i, s in enumerate(STAGES):
        if s.name == stage.name:
            STAGES[i] = stage
            return
    if after is None:
        STAGES.append(stage)
        return
    names = [s.name for s in STAGES]
    STAGES.insert(names.index(after) + 1, stage)


def stages() -> list[Stage]:
    for m in STAGE_MODULES:
        importlib.import_module(m)
    return list(STAGES)


@dataclass
class BuildContext:
    """What a stage sees: the recording (``hearth.robot.recording.Recording`` or a bag), the
    build directory, the configuration (stage name -> options), progress and warnings."""
    recording: Any
    source: Path
    out: Path
    config: dict = field(default_factory=dict)
    progress: Callable[[str], None] = lambda text: None
    warnings: list[str] = field(default_factory=list)
    results: dict = field(default_factory=dict)

    def path(self, relative: str) -> Path:
        p = self.out / relative
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def write_json(self, relative: str, data) -> Path:
        p = self.path(relative)
        tmp = p.with_name(p.name + ".tmp")
        tmp.write_text(json.dumps(data, indent=1, default=_jsonable) + "\n", encoding="utf-8")
        tmp.replace(p)
        return p

    def read_json(self, relative: str, stage: str):
        """An earlier stage's JSON output; a MappingError naming the file and the stage that
        writes it when it is missing or corrupt."""
        p = self.out / relative
        if not p.is_file():
            raise StageFailed(f"{p}: missing (run the {stage} stage first)")
        try:
            return json.loads(p.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as err:
            raise MappingError(f"corrupt stage output ({err}); rerun the {stage} stage",
                               file=str(p)) from None

    def warn(self, text: str) -> None:
        self.warnings.append(text)
        self.progress(f"  warning: {text}")


def _jsonable(x):
    import numpy as np
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    raise TypeError(f"not JSON: {type(x).__name__}")


@dataclass
class BuildResult:
    out: Path
    stages: dict
    failed: list[str]
    warnings: list[str]
    seconds: float


def build(recording_path, out, config: Optional[dict] = None, only: Optional[list[str]] = None,
          topics=None, progress: Callable[[str], None] = lambda text: None) -> BuildResult:
    """Run the stages (``only``: these, in pipeline order) on the recording at
    ``recording_path`` (a Hearth recording directory or a ROS 2 bag) into ``out``."""
    from hearth.mapping.inputs import open_tour
    all_stages = stages()
    names = [s.name for s in all_stages]
    if only:
        unknown = [n for n in only if n not in names]
        if unknown:
            raise MappingError(f"unknown stage {', '.join(unknown)} (stages: {', '.join(names)})")
    run = [s for s in all_stages if not only or s.name in only]
    t_start = time.perf_counter()
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise MappingError("exists and is not a directory: the build writes a directory",
                           file=str(out))
    rec = open_tour(recording_path, topics=topics)
    out.mkdir(parents=True, exist_ok=True)
    ctx = BuildContext(recording=rec, source=Path(recording_path), out=out,
                       config=dict(config or {}), progress=progress)
    previous = {}
    if only and (out / "build.json").is_file():
        try:
            previous = json.loads((out / "build.json").read_text()).get("stages", {})
        except (json.JSONDecodeError, UnicodeDecodeError, AttributeError):
            previous = {}
    done: dict = {k: v for k, v in previous.items() if k in names}
    failed: list[str] = []
    try:
        for k, stage in enumerate(run, 1):
            progress(f"{stage.name} ({k}/{len(run)}): {stage.summary}")
            t0 = time.perf_counter()
            try:
                info = stage.run(ctx) or {}
                status = "done"
            except StageFailed as err:
                info, status = {"error": str(err)}, "failed"
            except MappingError:
                raise
            except Exception as err:  # noqa: BLE001 - a bug or odd data in one stage: keep the rest
                from hearth.perception.errors import PerceptionError
                if not isinstance(err, PerceptionError):
                    ctx.warnings.append(f"{stage.name}: {traceback.format_exc(limit=3)}")
                info, status = {"error": f"{type(err).__name__}: {err}"}, "failed"
            dt = time.perf_counter() - t0
            done[stage.name] = dict(status=status, seconds=round(dt, 2)) | info
            ctx.results[stage.name] = done[stage.name]
            if status == "failed":
                failed.append(stage.name)
                progress(f"  {stage.name} failed: {info['error']}")
            else:
                progress(f"  {_one_line(info)} ({dt:.1f} s)")
    finally:
        close = getattr(rec, "close", None)
        if close:
            close()
    seconds = time.perf_counter() - t_start
    report = dict(recording=str(recording_path), captures=len(rec.captures),
                  stages_run=[s.name for s in run], stages=done,
                  seconds=round(seconds, 2), failed=failed, warnings=ctx.warnings)
    ctx.write_json("build.json", report)
    return BuildResult(out, done, failed, ctx.warnings, seconds)


def _one_line(info: dict) -> str:
    parts = []
    for k, v in info.items():
        if isinstance(v, (dict, list)) or k.startswith("_"):
            continue
        if isinstance(v, float):
            v = f"{v:.3g}" if math.isfinite(v) else str(v)
        parts.append(f"{k.replace('_', ' ')} {v}")
    return ", ".join(parts[:8])
