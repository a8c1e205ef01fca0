"""The report's lines on hybrid rows: each correction set against its own physics prior.

A hybrid row (``Row.prior_row``: the row that computes its prior exactly, e.g. residual-rnea on rnea)
keeps its prior when its correction does not beat the prior on validation (``prior_kept`` in
results.csv: "all", "none", or the joints that kept it). These lines state, per scenario, each
hybrid's test RMSE over its prior's and whether validation kept the prior, so a reader sees
both what the correction added and when it was switched off.
"""
from __future__ import annotations

import math

from .rows import ROWS


def hybrid_lines(rows) -> list[str]:
    """Markdown bullets (empty: no hybrid row ran beside its prior), from results.csv rows."""
    ok = {(r["scenario"], r["task"], r["model"]): r for r in rows if r.get("status") == "ok"}
    lines = []
    for (scenario, task, model), r in ok.items():
        spec = ROWS.get(model)
        prior = ok.get((scenario, task, spec.prior_row)) if spec is not None and spec.prior_row else None
        if prior is None:
            continue
        ratio = float(r["rmse"]) / float(prior["rmse"]) if float(prior["rmse"]) > 0 else math.nan
        kept = str(r.get("prior_kept") or "")
        said = {"all": "validation kept the prior (no correction)", "none": "corrected",
                "": "kept prior not recorded"}.get(kept, f"validation kept the prior on {kept}, corrected the rest")
        lines.append(f"- {scenario}: `{model}` {float(r['rmse']):.4f} against its prior `{spec.prior_row}` "
                     f"{float(prior['rmse']):.4f} (test RMSE, x{ratio:.3f}); {said}")
    if not lines:
        return []
    return ["", "## Hybrid rows against their physics prior", "",
            "Each row that corrects a physics model, beside the row that is that model (test RMSE and their "
            "ratio). A hybrid keeps its prior where its correction does not beat the prior on validation: a "
            "residual net keeps its untrained, zero-output weights (`best_epoch` -1), the residual GP zeroes "
            "the joints it does not improve (`prior_kept` in results.csv).", ""] + lines
