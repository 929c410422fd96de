"""What a scenario suite found (``report``: ``scenarios.summarise`` plus per-home counts, wrong
successes, the slowest scenarios and the problems), for a person (``headline``,
``render_text``) and as a picture (``render_png``: success per home and mission, OpenCV)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

from hearth.executive.suite_bundles import _write_atomic
from hearth.executive.suite_worker import case_key


# ---------------------------------------------------------------------------------------
# The report
# ---------------------------------------------------------------------------------------
def report(results: list[dict], cases: Optional[list] = None) -> dict:
    """What a suite found: ``summary`` (``scenarios.summarise``), per mission and per home
    the counts behind the success rates (learned search order, as ``summarise``), wrong
    successes per world and per object type, the ten slowest scenarios and every problem
    (crashed, timed out, raised) with its traceback."""
    from collections import Counter, defaultdict

    from hearth.executive.scenarios import summarise
    order = {case_key(c): i for i, c in enumerate(cases)} if cases is not None else {}
    rs = sorted(results, key=lambda r: order.get(r.get("key"), len(order)))
    main = [r for r in rs if r.get("learned", True)]
    per_home: dict[str, dict] = defaultdict(dict)
    per_mission: dict[str, dict] = {}
    for m in sorted({r["mission"] for r in rs}):
        rm = [r for r in main if r["mission"] == m]
        per_mission[m] = _counts(rm)
        for w in dict.fromkeys(r.get("world", "demo") for r in rm):
            per_home[w][m] = _counts([r for r in rm if r.get("world", "demo") == w])
    wrong = [r for r in rs if r.get("wrong_success")]
    problems = [dict(key=r.get("key"), world=r.get("world"), mission=r["mission"],
                     seed=r["seed"], target=r.get("target"), error=r.get("error"),
                     reason=r["reason"], traceback=r.get("traceback"),
                     wall_time_s=r.get("wall_time_s"))
                for r in rs if r.get("error") or r["outcome"] == "error"]
    slowest = sorted((r for r in rs if not r.get("error")), key=lambda r: -r["wall_time_s"])[:10]
    return {
        "scenarios": len(cases) if cases is not None else len(rs),
        "results": len(rs),
        # Warm-up runs (learned: false) fill the learned search order; the tables count
        # the others.
        "warmup_runs": len(rs) - len(main),
        "per_mission": per_mission,
        "per_home": dict(per_home),
        "wrong_success": {
            "total": len(wrong),
            "by_world": dict(Counter(r.get("world", "demo") for r in wrong)),
            "by_object_type": dict(Counter(r.get("target_type") or "?" for r in wrong)),
            "by_mission": dict(Counter(r["mission"] for r in wrong)),
        },
        "problems": problems,
        "problem_counts": dict(Counter(p["error"] or "error" for p in problems)),
        "slowest": [dict(world=r.get("world"), mission=r["mission"], target=r.get("target"),
                         seed=r["seed"], learned=r.get("learned", True), outcome=r["outcome"],
                         wall_time_s=r["wall_time_s"], sim_time_s=r.get("sim_time_s"))
                    for r in slowest],
        "summary": summarise(rs) if rs else {},
    }


def _counts(rs: list[dict]) -> dict:
    ach = [r for r in rs if r["achievable"]]
    una = [r for r in rs if not r["achievable"]]
    ok = sum(bool(r["correct"]) for r in rs)
    return {"scenarios": len(rs), "correct": ok,
            "rate": round(ok / len(rs), 3) if rs else None,
            "achievable": len(ach), "succeeded": sum(bool(r["correct"]) for r in ach),
            "success_rate": round(sum(bool(r["correct"]) for r in ach) / len(ach), 3)
            if ach else None,
            "unachievable": len(una), "unachievable_correct": sum(bool(r["correct"]) for r in una),
            "wrong_success": sum(bool(r.get("wrong_success")) for r in rs),
            "errors": sum(bool(r.get("error")) or r["outcome"] == "error" for r in rs)}


def headline(rep: dict, ran: int, wall_s: float, resumed: int = 0) -> str:
    """The first line of a suite's report: the scenarios its tables count (warm-up runs
    apart), how many ran now, where and how long."""
    warm = rep.get("warmup_runs", 0)
    return (f"{rep['results'] - warm} scenarios" + (f" and {warm} warm-up runs" if warm else "")
            + f" ({ran} run now on {rep['engine']} in {wall_s:.1f} s"
            + (f", {resumed} from the results file" if resumed else "") + ")")


def render_text(rep: dict, top: int = 5) -> str:
    """The report for a person."""
    lines = []
    missions = list(rep["per_mission"])
    lines.append("Per mission (success: achievable scenarios that succeeded, learned order; "
                 "unachievable: ended with the right failure)")
    lines.append(f"  {'mission':<22}{'scenarios':>10}{'success':>14}{'unachievable':>15}"
                 f"{'wrong':>7}{'errors':>8}")
    for m, c in rep["per_mission"].items():
        lines.append(f"  {m:<22}{c['scenarios']:>10}{_frac(c['succeeded'], c['achievable']):>14}"
                     f"{_frac(c['unachievable_correct'], c['unachievable']):>15}"
                     f"{c['wrong_success']:>7}{c['errors']:>8}")
    lines.append("")
    lines.append("Per home (scenarios that ended right / scenarios; ! wrong successes, "
                 "E errors)")
    width = max([len(w) for w in rep["per_home"]] + [6]) + 2
    lines.append("  " + "home".ljust(width) + "".join(f"{m:>22}" for m in missions))
    for w, ms in rep["per_home"].items():
        cells = []
        for m in missions:
            c = ms.get(m)
            if c is None:
                cells.append(f"{'-':>22}")
                continue
            mark = (f" !{c['wrong_success']}" if c["wrong_success"] else "") + \
                   (f" E{c['errors']}" if c["errors"] else "")
            cells.append(f"{_frac(c['correct'], c['scenarios']) + mark:>22}")
        lines.append("  " + w.ljust(width) + "".join(cells))
    ws = rep["wrong_success"]
    lines.append("")
    if ws["total"]:
        lines.append(f"Wrong successes: {ws['total']} (by home: {_pairs(ws['by_world'])}; by "
                     f"object type: {_pairs(ws['by_object_type'])})")
    else:
        lines.append("Wrong successes: none")
    if rep["slowest"]:
        lines.append("")
        lines.append("Slowest scenarios (wall seconds)")
        for s in rep["slowest"][:top]:
            lines.append(f"  {s['wall_time_s']:>7.1f} s  {s['world']} {s['mission']} "
                         f"{s['target'] or ''} seed {s['seed']}"
                         f"{'' if s['learned'] else ' (fixed order)'}: {s['outcome']}")
    if rep["problems"]:
        lines.append("")
        lines.append(f"Problems: {_pairs(rep['problem_counts'])}")
        for p in rep["problems"]:
            lines.append(f"  {p['world']} {p['mission']} {p['target'] or ''} seed {p['seed']}: "
                         f"{p['error'] or 'error'}: {p['reason']}")
            for tl in (p["traceback"] or "").rstrip().splitlines()[-12:]:
                lines.append(f"      {tl}")
    return "\n".join(lines)


def _frac(k: int, n: int) -> str:
    return f"{k}/{n} {k / n:.2f}" if n else "-"


def _pairs(d: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(d.items())) or "none"


def render_png(rep: dict, path) -> Path:
    """Success per home (rows) and mission (columns) as a grid: each cell coloured from red
    (none ended right) to green (all did), with the count; ``!N`` wrong successes, ``EN``
    errors (crashed, timed out, raised). OpenCV, no plotting library."""
    import cv2
    import numpy as np
    missions = list(rep["per_mission"])
    homes = list(rep["per_home"])
    font, cell_w, cell_h, pad = cv2.FONT_HERSHEY_SIMPLEX, 190, 44, 12
    label_w = max([cv2.getTextSize(h, font, 0.5, 1)[0][0] for h in homes] + [60]) + 2 * pad
    top, bottom = 70, 70
    total = sum(c["scenarios"] for c in rep["per_mission"].values())
    ok = sum(c["correct"] for c in rep["per_mission"].values())
    title = (f"hearth suite: {ok}/{total} scenarios ended right, "
             f"{rep['wrong_success']['total']} wrong successes, {len(rep['problems'])} errors")
    legend = "0 % ... 100 % ended right;  !N wrong successes;  EN errors"
    W = max(label_w + cell_w * max(1, len(missions)),
            cv2.getTextSize(title, font, 0.55, 1)[0][0],
            250 + cv2.getTextSize(legend, font, 0.45, 1)[0][0]) + 2 * pad
    H = top + cell_h * max(1, len(homes)) + bottom
    img = np.full((H, W, 3), 255, np.uint8)
    cv2.putText(img, title, (pad, 26), font, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    for j, m in enumerate(missions):
        x = label_w + j * cell_w
        cv2.putText(img, m, (x + 6, top - 12), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    for i, h in enumerate(homes):
        y = top + i * cell_h
        cv2.putText(img, h, (pad, y + cell_h // 2 + 5), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        for j, m in enumerate(missions):
            x = label_w + j * cell_w
            c = rep["per_home"][h].get(m)
            if c is None or not c["scenarios"]:
                colour, text = (235, 235, 235), "-"
            else:
                colour = _colour(c["correct"] / c["scenarios"])
                text = f"{c['correct']}/{c['scenarios']}"
                if c["wrong_success"]:
                    text += f"  !{c['wrong_success']}"
                if c["errors"]:
                    text += f"  E{c['errors']}"
            cv2.rectangle(img, (x, y), (x + cell_w - 2, y + cell_h - 2), colour, -1)
            cv2.putText(img, text, (x + 10, y + cell_h // 2 + 6), font, 0.55, (20, 20, 20), 1,
                        cv2.LINE_AA)
    y = H - bottom + 22
    for k in range(11):
        x = pad + k * 22
        cv2.rectangle(img, (x, y), (x + 20, y + 14), _colour(k / 10), -1)
    cv2.putText(img, legend, (pad + 250, y + 12), font, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _, png = cv2.imencode(".png", img)
    _write_atomic(path, png.tobytes())
    return path


def _colour(f: float) -> tuple[int, int, int]:
    """Red (0) through yellow to green (1), BGR."""
    f = min(1.0, max(0.0, f))
    r = 220 if f < 0.5 else int(220 - (f - 0.5) * 2 * 150)
    g = int(80 + f * 2 * 120) if f < 0.5 else 200
    return (90, g, r)
