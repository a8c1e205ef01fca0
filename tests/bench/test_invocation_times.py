"""The wall time a report prints: its invocations since the last that began on empty caches."""
from hybrid_dyn.bench.report import _invocation_times


def test_a_cold_invocation_starts_the_count_and_earlier_ones_are_not_added():
    older = {"wall_seconds": 1176.0, "finished": "2026-12-03T17:41:40Z"}  # another code's run, other caches
    cold = {"wall_seconds": 2294.0, "finished": "2026-12-05T16:55:02Z", "cold_start": True}
    assert _invocation_times([older, cold]) == "; it began on empty caches"
    resumed = {"wall_seconds": 600.0, "finished": "2026-12-05T18:00:00Z"}
    assert _invocation_times([older, cold, resumed]) == "; all invocations [min]: 38.2, 10.0; in all 48.2 min"


def test_without_a_recorded_cold_start_every_invocation_counts():
    parts = [{"wall_seconds": 60.0, "finished": "x"}, {"wall_seconds": 120.0, "finished": "y"}]
    assert _invocation_times(parts) == "; all invocations [min]: 1.0, 2.0; in all 3.0 min"
    assert _invocation_times(parts[:1]) == ""
