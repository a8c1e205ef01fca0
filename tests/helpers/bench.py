"""A tiny bench profile for imported logs (a few rows of each kind, a few training steps)."""

# A few rows of each kind, to keep the test seconds: analytic (one runs, one needs a base sensor), a tip-force
# net (no tip force in a log), a seed net (trains one tiny epoch) and a row identified on the log itself.
ROWS = ["rnea", "rnea-bw", "torques-pinv", "seed-tip-1", "seed-tau-mlp", "identified-ols"]


def tiny_profile(data, **kw):
    """``profile_for_data(data)`` running only ROWS, one worker, two training steps."""
    from hybrid_dyn.bench.profiles import profile_for_data

    return profile_for_data(data, families=(), rows=tuple(ROWS), workers=1,
                            train=dict(budget_steps=2, budget_evals=1, batch_size=64, progress=False), **kw)
