"""hybrid_dyn.timing: the one timer of every speed figure (the bench, the streaming runtime, benchmarks/)."""
import numpy as np
import pytest

from hybrid_dyn import timing


class FakeClock:
    """perf_counter and thread_time that advance only when a call says how long it took."""

    def __init__(self):
        self.wall = self.cpu = 0.0

    def spend(self, wall, cpu=None):
        self.wall += wall
        self.cpu += wall if cpu is None else cpu


@pytest.fixture
def clock(monkeypatch):
    c = FakeClock()
    monkeypatch.setattr(timing.time, "perf_counter", lambda: c.wall)
    monkeypatch.setattr(timing.time, "thread_time", lambda: c.cpu)
    return c


def test_time_calls_times_each_call_alone_and_its_cpu(clock):
    seen = []

    def call(k):
        seen.append(k)
        clock.spend(wall=k * 1e-3, cpu=k * 1e-4)  # a preempted call: wall far above its CPU time

    wall, cpu = timing.time_calls(call, range(3, 6), cpu=True)
    assert seen == [3, 4, 5]  # in order: a stream is fed as a control loop feeds it
    np.testing.assert_allclose(wall, [3e-3, 4e-3, 5e-3])
    np.testing.assert_allclose(cpu, [3e-4, 4e-4, 5e-4])
    assert timing.time_calls(call, [1])[1] is None


def test_median_call_us_leaves_the_warm_up_untimed(clock):
    costs = iter([1.0] * 5 + [2e-6, 4e-6, 9e-6])  # five slow first calls (lazy set-up), then three timed

    def call():
        clock.spend(next(costs))

    assert timing.median_call_us(call, 3, warmup=5) == pytest.approx(4.0)
    with pytest.raises(ValueError, match="at least one call"):
        timing.median_call_us(call, 0)


def test_per_item_us_is_the_median_run_of_mean_calls_per_item(clock):
    costs = [1e-3] * 4 + [3e-3] * 4 + [2e-3] * 4  # three runs of four calls, each run at one cost
    calls = iter(costs)

    def call():
        clock.spend(next(calls))

    # per item: cost / 10 items; the median run's: 2e-3 s / 10 = 200 us
    assert timing.per_item_us(call, per=10, repeat=3, number=4) == pytest.approx(200.0)
    assert next(calls, None) is None  # exactly repeat x number calls


def test_interleaved_rates_warm_each_step_then_take_turns(clock):
    order = []

    def step(name, cost):
        def run():
            order.append(name)
            clock.spend(cost)
        return run

    rates = timing.interleaved_rates([(step("a", 0.01), 100), (step("b", 0.04), 200)], n_steps=2, repeats=2,
                                     warmup=1)
    assert order == ["a", "b", "a", "a", "b", "b", "a", "a", "b", "b"]  # warm-ups, then turns per round
    assert rates == pytest.approx([100 / 0.01, 200 / 0.04])


def test_stopwatch_gives_wall_and_cpu_of_the_block(monkeypatch, clock):
    cpu = iter([10.0, 13.0])
    monkeypatch.setattr(timing, "cpu_seconds", lambda: next(cpu))
    with timing.Stopwatch() as sw:
        clock.spend(2.0)
    assert sw.wall == pytest.approx(2.0) and sw.cpu == pytest.approx(3.0) and sw.cores == pytest.approx(1.5)


def test_cpu_seconds_grows_with_work():
    t0 = timing.cpu_seconds()
    x = 0
    for i in range(200_000):
        x += i * i
    assert timing.cpu_seconds() > t0
