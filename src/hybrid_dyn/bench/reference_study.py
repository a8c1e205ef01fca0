"""The reference study (Kružić et al. 2021, whose nets the ``seed-*`` rows rebuild): its published
tables, and the report's section that sets a bench report's rows beside them.

The design in full: ``docs/design/bench.md`` (reference_study.py).
"""
from __future__ import annotations

import statistics

from .catalog import ROWS  # noqa: F401  (every row declared, for is_physics_result)
from .rows import is_physics_result

# Table 2: tip-force nets (architectures of Table 1): validation loss, test loss, RMSE [N].
REFERENCE_TABLE2 = {
    "seed-tip-1": (1.6544, 1.6629, 0.6871),
    "seed-tip-2": (0.9637, 0.9513, 0.5036),
    "seed-tip-3": (1.3130, 1.2956, 0.5440),
    "seed-tip-4": (1.1958, 1.1644, 0.4673),
    "seed-tip-5": (1.3665, 1.3101, 0.5047),
    "seed-tip-6": (0.9462, 0.9535, 0.4637),
    "seed-tip-7": (0.4790, 0.4590, 0.3204),
    "seed-tip-8": (0.4868, 0.4776, 0.2740),
    "seed-tip-9": (0.5422, 0.5100, 0.3224),
    "seed-tip-10": (0.1804, 0.1752, 0.1647),
    "seed-tip-11": (0.1788, 0.1649, 0.1533),
}

# Table 1: what each tip-force architecture is (for the table's description column).
REFERENCE_TABLE1 = {
    "seed-tip-1": "MLP, no torques, FC 2x32",
    "seed-tip-2": "MLP, torques, FC 2x32",
    "seed-tip-3": "MLP, torques, FC 2x16",
    "seed-tip-4": "Conv, no torques, FC 2x16, L=10",
    "seed-tip-5": "Conv, no torques, FC 2x16, L=5",
    "seed-tip-6": "Conv, torques, FC 2x16, L=5",
    "seed-tip-7": "LSTM, no torques, FC 2x16, L=10",
    "seed-tip-8": "LSTM, torques, FC 2x16, L=10",
    "seed-tip-9": "LSTM, torques, FC 2x16, L=5",
    "seed-tip-10": "LSTM* 2x32, no torques, FC 2x16, L=10",
    "seed-tip-11": "LSTM* 2x32, torques, FC 2x8, L=10",
}

# Table 3: joint-torque nets. (model, data set) -> (validation loss, test loss, RMSE [Nm]).
REFERENCE_TABLE3 = {
    ("delan", "sim-noext"): (0.6528, 0.6826, 0.5314),
    ("delan", "sim-ext"): (1.2333, 1.2137, 0.7475),
    ("seed-tau-mlp", "sim-ext"): (1.4070, 1.4076, 1.0287),
    ("seed-tau-conv", "sim-ext"): (1.1439, 1.1420, 0.9144),
    ("seed-tau-lstm", "sim-ext"): (0.6208, 0.6236, 0.6189),
    ("delan", "real"): (1.3198, 1.2398, 0.8468),
    ("seed-tau-mlp", "real"): (1.9336, 1.8995, 1.1567),
    ("seed-tau-conv", "real"): (1.4699, 1.4837, 0.9552),
    ("seed-tau-lstm", "real"): (1.1643, 1.0385, 0.7778),
    ("seed-tau-lstm-opt", "sim-ext"): (0.3171, 0.3186, 0.5115),
}

# Gaz et al. 2019: identified model on the real Panda, validation torque RMSE per joint [Nm].
GAZ2019_VALIDATION_RMSE = (0.64, 1.01, 0.77, 0.65, 0.42, 0.20, 0.16)


def reference_dataset_label(scenario: str) -> str | None:
    """Which of the reference study's data sets a toolkit scenario mirrors (PROTOCOL 2): a simulated scenario's declared
    ``seed_dataset`` (``sim/scenarios.py``), "real" for the real-robot logs, else None."""
    from ..sim.scenarios import SCENARIOS

    if scenario in SCENARIOS:
        return SCENARIOS[scenario].seed_dataset
    if scenario.startswith("real"):
        return "real"
    return None


REFERENCE_COMPARISON_FILE = "seed_comparison.md"

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
    ours, theirs = {}, {}
    for i in range(1, 12):
        name = f"seed-tip-{i}"
        r = ok.get(("tip_force", name))
        published = REFERENCE_TABLE2[name][2]
        if r is None:
            out.append(f"| {i} | {REFERENCE_TABLE1[name]} | - | - | - | {published:.4f} | - |")
            continue
        rmse = float(r["rmse"])
        ours[i], theirs[i] = rmse, published
        out.append(f"| {i} | {REFERENCE_TABLE1[name]} | {rmse:.4f} | {r.get('epochs', '')} ({r.get('stopped_by', '')}) | "
                   f"{_kept_losses(curves.get(name))} | {published:.4f} | {rmse / published:.2f} |")
    raw = ok.get(("tip_force", "seed-tip-11-raw"))
    if raw is not None:
        out += ["", f"`seed-tip-11-raw` (#11 on the untared sensor, a reference): {float(raw['rmse']):.4f} N."]
    if ours:
        best_here = {a: min(ours[i] for i in ids if i in ours) for a, ids in ARCHITECTURES.items()
                     if any(i in ours for i in ids)}
        best_theirs = {a: min(theirs[i] for i in ids if i in theirs) for a, ids in ARCHITECTURES.items() if a in best_here}
        med_here = {a: statistics.median(ours[i] for i in ids if i in ours) for a, ids in ARCHITECTURES.items()
                    if a in best_here}
        median_theirs = {a: statistics.median(theirs[i] for i in ids if i in theirs) for a, ids in ARCHITECTURES.items()
                    if a in best_here}
        out += ["", "Architecture ordering (test RMSE [N], lower is better):", "",
                f"- best of each, here: {_order(best_here)}",
                f"- best of each, seed: {_order(best_theirs)}",
                f"- median of each, here: {_order(med_here)}",
                f"- median of each, seed: {_order(median_theirs)}"]
    out += ["", "### Table 3: joint-torque nets", "",
            "| model | RMSE here [Nm] | epochs or rounds (stop) | train / val loss, kept epoch or round | seed RMSE, sim-ext [Nm] | "
            "here / seed | seed RMSE, sim-noext [Nm] |",
            "|---|---|---|---|---|---|---|"]
    for name in TORQUE_NETS:
        r = ok.get(("joint_torque", name))
        ext = REFERENCE_TABLE3.get(("delan" if name.startswith("delan") else name, "sim-ext"))
        noext = REFERENCE_TABLE3.get(("delan" if name.startswith("delan") else name, "sim-noext"))
        if r is None:
            continue
        rmse = float(r["rmse"])
        out.append(f"| {name} | {rmse:.4f} | {r.get('epochs', '')} ({r.get('stopped_by', '')}) | "
                   f"{_kept_losses(curves.get(name))} | {'-' if ext is None else f'{ext[2]:.4f}'} | {'-' if ext is None else f'{rmse / ext[2]:.2f}'} | "
                   f"{'-' if noext is None else f'{noext[2]:.4f}'} |")
    out += ["", "### The analytic rows on the same test split", ""]
    for task, unit in (("tip_force", "N"), ("joint_torque", "Nm")):
        # A row that refused every test sample has no RMSE to rank by.
        cand = [r for (t, _), r in ok.items() if t == task and is_physics_result(r) and r.get("rmse") not in (None, "")]
        for r in sorted(cand, key=lambda r: float(r["rmse"]))[:3]:
            out.append(f"- {task}: `{r['model']}` {float(r['rmse']):.4f} {unit}")
    return "\n".join(out) + "\n"


def reference_comparison_text(rows: list[dict], curves: dict | None = None) -> str | None:
    """The section for every scenario of ``rows`` (results.csv's) that holds one of the reference study's nets;
    None when none does."""
    scenarios = [s for s in dict.fromkeys(r["scenario"] for r in rows)
                 if any(r["scenario"] == s and r.get("status") == "ok"
                        and (r["model"] in REFERENCE_TABLE2 or r["model"] in TORQUE_NETS) for r in rows)]
    if not scenarios:
        return None
    return "# The seed's Tables 2 and 3 beside this report\n\n" + "\n".join(comparison(rows, s, curves)
                                                                          for s in scenarios)
