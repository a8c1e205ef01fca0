"""The report's section "hardware sensors against ideal sensors": each row's RMSE on a scenario read by the
hardware sensor model (``sim/sensors.py``) over its RMSE on the same runs read by the legacy ideal sensors
(its reference scenario, named ``<scenario>-ideal``: ``paper-ext-ideal``), row by row, drawn from results.csv
alone. A ratio above 1 is what the hardware read costs that row."""
from __future__ import annotations

import math

from .report_tables import answered_share, low_answer

IDEAL_SUFFIX = "-ideal"  # a reference scenario's name: the scenario it is the reference of, read by ideal sensors


def _rmse(r) -> float:
    try:
        return float(r["rmse"]) if r.get("status") == "ok" else math.nan
    except (TypeError, ValueError):
        return math.nan


def hardware_vs_ideal_pairs(rows) -> list[tuple[str, str]]:
    """(hardware scenario, its ideal-sensor reference) for every reference scenario whose scenario is in ``rows`` too."""
    scenarios = list(dict.fromkeys(r["scenario"] for r in rows))
    return [(s[: -len(IDEAL_SUFFIX)], s) for s in scenarios
            if s.endswith(IDEAL_SUFFIX) and s[: -len(IDEAL_SUFFIX)] in scenarios]


def hardware_vs_ideal_lines(rows) -> list[str]:
    """The README's section: per pair and task, each row's RMSE on both and their ratio, the dearest first."""
    lines = []
    for hard, ideal in hardware_vs_ideal_pairs(rows):
        for task, unit in (("tip_force", "N"), ("joint_torque", "Nm")):
            both = {}
            for r in rows:
                if r["task"] == task and r["scenario"] in (hard, ideal):
                    both.setdefault(r["model"], {})[r["scenario"]] = r
            pairs = [(m, d[hard], d[ideal]) for m, d in both.items() if hard in d and ideal in d]
            if not pairs:
                continue
            pairs.sort(key=lambda p: -(_rmse(p[1]) / _rmse(p[2]) if _rmse(p[2]) > 0 else math.inf))
            lines += [f"### {hard} against {ideal}, {task.replace('_', ' ')}", "",
                      f"| model | family | RMSE {hard} [{unit}] | RMSE {ideal} [{unit}] | ratio | answered {hard} |",
                      "|---|---|---|---|---|---|"]
            for m, h, i in pairs:
                a, b = _rmse(h), _rmse(i)
                ratio = a / b if b > 0 else math.nan
                mark = " §" if low_answer(h) or low_answer(i) else ""
                lines.append(f"| {m}{mark} | {h.get('family', '')} | {a:.4f} | {b:.4f} | {ratio:.2f} | "
                             f"{100 * answered_share(h):.1f} % |")
            lines.append("")
    if not lines:
        return []
    return ["", "## Hardware sensors against ideal sensors", "",
            "Each row's test RMSE on a scenario read by the hardware sensor model (q quantized to the robot's "
            "encoder resolution, qd the drive's difference of it at 1 kHz, the base sensor's bias drift, stamp "
            "jitter: `sim/sensors.py`) over its RMSE on the same runs (the same trajectories and forces) read by "
            "the legacy ideal sensors (white noise on q and qd, a constant bias). Above 1: what the hardware read "
            "costs the row; the dearest first. §: answered under 95 % of the test samples on one of the two.", "",
            *lines]
