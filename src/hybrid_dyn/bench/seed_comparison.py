"""The seed's Tables 2 and 3 beside a bench report's rows, and the architecture ordering (issues 14, 31).

A section of every report that holds the seed's nets (``seed_comparison.md``, written by the bench
and redrawn by ``hybrid-dyn report``), per scenario:

- Table 2: every seed tip-force net (Table 1 #1-#11), our test RMSE [N] beside the seed's,
  and the ratio; then the best and the median of each architecture (MLP #1-3, conv #4-6,
  LSTM #7-11) here and in the seed, and the ordering each gives.
- Table 3: the seed's torque nets and DeLaN, our test RMSE [Nm] beside the seed's
  (its ``sim-ext`` figures; DeLaN also beside its ``sim-noext`` one).
- The best analytic rows of each task, which on noise-free data with exact states are
  nearly exact: the bar the seed's nets never had to clear.
- Beside each net, its training and validation loss at the kept round (from the report's
  ``curves.json``): a validation loss many times the training loss is a net that fits the
  training instances and does not carry over to others (overfitting), not one that cannot fit.

The seed's figures come from another simulator (CoppeliaSim/Newton) and another data set:
orientation, not a measurement here.
"""
from __future__ import annotations

import statistics

from .catalog import ROWS  # noqa: F401  (every row declared, for is_physics_result)
from .rows import is_physics_result
from .seed_reference import SEED_TABLE1, SEED_TABLE2, SEED_TABLE3

SEED_COMPARISON_FILE = "seed_comparison.md"

ARCHITECTURES = {"MLP": (1, 2, 3), "conv": (4, 5, 6), "LSTM": (7, 8, 9, 10, 11)}
TORQUE_NETS = ("seed-tau-mlp", "seed-tau-conv", "seed-tau-lstm", "seed-tau-lstm-opt", "delan", "delan-friction")


def _order(figures: dict) -> str:
    return " < ".join(f"{k} ({v:.3f})" for k, v in sorted(figures.items(), key=lambda kv: kv[1]))


def _kept_losses(curve: dict | None) -> str:
    """'train / val (val/train)' at the kept epoch (epoch recipes) or validation round (budget) of a learned row's curve, or '-'."""
    if not curve or curve.get("best_epoch", -1) < 0:
        return "-"
    e = curve["history"][curve["best_epoch"]]
    return f"{e['train_loss']:.4f} / {e['val_loss']:.4f} ({e['val_loss'] / e['train_loss']:.1f}x)"


def comparison(rows: list[dict], scenario: str, curves: dict | None = None) -> str:
    ok = {(r["task"], r["model"]): r for r in rows if r["scenario"] == scenario and r.get("status") == "ok"}
    curves = (curves or {}).get(scenario, {})
    out = [f"## {scenario}", "",
           "The seed's figures (Kruzic et al. 2021) are from CoppeliaSim/Newton and another data set: shown for "
           "orientation, not measured here.", "",
           "### Table 2: tip-force nets", "",
           "| # | architecture (seed Table 1) | RMSE here [N] | epochs or rounds (stop) | train / val loss, kept epoch or round | "
           "seed RMSE [N] | here / seed |",
           "|---|---|---|---|---|---|---|"]
    ours, seeds = {}, {}
    for i in range(1, 12):
        name = f"seed-tip-{i}"
        r = ok.get(("tip_force", name))
        seed = SEED_TABLE2[name][2]
        if r is None:
            out.append(f"| {i} | {SEED_TABLE1[name]} | - | - | - | {seed:.4f} | - |")
            continue
        rmse = float(r["rmse"])
        ours[i], seeds[i] = rmse, seed
        out.append(f"| {i} | {SEED_TABLE1[name]} | {rmse:.4f} | {r.get('epochs', '')} ({r.get('stopped_by', '')}) | "
                   f"{_kept_losses(curves.get(name))} | {seed:.4f} | {rmse / seed:.2f} |")
    raw = ok.get(("tip_force", "seed-tip-11-raw"))
    if raw is not None:
        out += ["", f"`seed-tip-11-raw` (#11 on the untared sensor, a reference): {float(raw['rmse']):.4f} N."]
    if ours:
        best_here = {a: min(ours[i] for i in ids if i in ours) for a, ids in ARCHITECTURES.items()
                     if any(i in ours for i in ids)}
        best_seed = {a: min(seeds[i] for i in ids if i in seeds) for a, ids in ARCHITECTURES.items() if a in best_here}
        med_here = {a: statistics.median(ours[i] for i in ids if i in ours) for a, ids in ARCHITECTURES.items()
                    if a in best_here}
        med_seed = {a: statistics.median(seeds[i] for i in ids if i in seeds) for a, ids in ARCHITECTURES.items()
                    if a in best_here}
        out += ["", "Architecture ordering (test RMSE [N], lower is better):", "",
                f"- best of each, here: {_order(best_here)}",
                f"- best of each, seed: {_order(best_seed)}",
                f"- median of each, here: {_order(med_here)}",
                f"- median of each, seed: {_order(med_seed)}"]
    out += ["", "### Table 3: joint-torque nets", "",
            "| model | RMSE here [Nm] | epochs or rounds (stop) | train / val loss, kept epoch or round | seed RMSE, sim-ext [Nm] | "
            "here / seed | seed RMSE, sim-noext [Nm] |",
            "|---|---|---|---|---|---|---|"]
    for name in TORQUE_NETS:
        r = ok.get(("joint_torque", name))
        ext = SEED_TABLE3.get(("delan" if name.startswith("delan") else name, "sim-ext"))
        noext = SEED_TABLE3.get(("delan" if name.startswith("delan") else name, "sim-noext"))
        if r is None:
            continue
        rmse = float(r["rmse"])
        out.append(f"| {name} | {rmse:.4f} | {r.get('epochs', '')} ({r.get('stopped_by', '')}) | "
                   f"{_kept_losses(curves.get(name))} | {'-' if ext is None else f'{ext[2]:.4f}'} | {'-' if ext is None else f'{rmse / ext[2]:.2f}'} | "
                   f"{'-' if noext is None else f'{noext[2]:.4f}'} |")
    out += ["", "### The analytic rows on the same test split", ""]
    for task, unit in (("tip_force", "N"), ("joint_torque", "Nm")):
        cand = [r for (t, _), r in ok.items() if t == task and is_physics_result(r)]
        for r in sorted(cand, key=lambda r: float(r["rmse"]))[:3]:
            out.append(f"- {task}: `{r['model']}` {float(r['rmse']):.4f} {unit}")
    return "\n".join(out) + "\n"


def seed_comparison_text(rows: list[dict], curves: dict | None = None) -> str | None:
    """The section for every scenario of ``rows`` (results.csv's) that holds a seed net; None when none does."""
    scenarios = [s for s in dict.fromkeys(r["scenario"] for r in rows)
                 if any(r["scenario"] == s and r.get("status") == "ok"
                        and (r["model"] in SEED_TABLE2 or r["model"] in TORQUE_NETS) for r in rows)]
    if not scenarios:
        return None
    return "# The seed's Tables 2 and 3 beside this report\n\n" + "\n".join(comparison(rows, s, curves)
                                                                          for s in scenarios)
