"""The streaming estimator never says "ok" to garbage.

The floor test feeds 10,000 calls that mix good samples with bad ones (NaN, inf, huge values, wrong
types and shapes, q past its limits, qd past the velocity limits, time going back or missing, a wrong
rate) to every registered analytic method, in both modes. No call may return "ok" with a force beyond the
bound, every bad sample must be rejected, and every good call must give exactly what the run without
the bad samples gives. The other tests reproduce the issue's cases one by one.
"""
import numpy as np
import pytest

from hybrid_dyn.analytic.methods import TIP_FORCE_METHODS
from hybrid_dyn.estimator import EstimatorInputError, EstimatorStatus, TipForceEstimator

from helpers.motion import CONTACT_AT, HZ, contact_stream, sine_motion

BOUND = 500.0  # EstimatorConfig.max_tip_force's default [N]
NEEDS = {m.name: ("q", "qd") + m.reads for m in TIP_FORCE_METHODS.values()}  # every registered method


# The stream is the model's own (no model error): the error bar's stated model term (estimator/model_term.py) has
# nothing to carry here, and these tests are about other things.
EXACT_MODEL = {"inertial_uncertainty": 0.0, "payload_uncertainty_kg": 0.0}


def stream(robot, n, hz=HZ, seed=0):
    """Exact rigid-body samples of a smooth motion about home with a 20 N tip-force bell at 0.9 s."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / hz
    q, qd, qdd = sine_motion(robot, t, rng, (0.1, 0.3))
    f = 20.0 * np.exp(-((t - 0.9) ** 2) / (2 * 0.1**2))[:, None] * np.array([0.6, 0.0, -0.8])
    jv = robot.tip_jacobian(q)[:, :3]
    tau = robot.inverse_dynamics(q, qd, qdd) - np.einsum("nij,ni->nj", jv, f)
    return [dict(q=q[k], qd=qd[k], base_wrench=w_k, tau_J=tau[k], t=t[k])
            for k, w_k in enumerate(robot.base_wrench(q, qd, qdd, tip_force=f))]


def bad_sample(rng, robot, needs, good, last_t, period, optional=()):
    """A corrupted copy of the next good sample; only inputs the estimator reads (``needs``) are
    corrupted (an input it ignores may hold anything). period: the stream's step [s]."""
    s = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in good.items()}
    name = needs[rng.integers(len(needs))]
    j = int(rng.integers(len(s[name])))
    kind = rng.integers(14)
    if kind == 0:
        s[name][j] = np.nan
    elif kind == 1:
        s[name][j] = rng.choice([np.inf, -np.inf])
    elif kind == 2:
        s[name][j] = rng.choice([1e12, -1e12, 1e150, -1e300])
    elif kind == 3:  # past a joint limit by more than the 0.1 rad margin
        s["q"][j] = robot.q_upper[j] + rng.uniform(0.15, 10.0) if rng.random() < 0.5 else robot.q_lower[j] - 10.0
    elif kind == 4:  # twice the velocity limit
        s["qd"][j] = 2.0 * robot.spec.max_velocity[j] * rng.choice([-1, 1])
    elif kind == 5:  # beyond its bound, but not absurd: 5 rad, 4.5 rad/s, 3x the effort limit, 4.5 kN(m)
        s[name][j] = {"q": 5.0, "qd": 4.5, "tau_J": 3.0 * robot.model.effortLimit[j]}.get(name, 4.5e3)
    elif kind == 6:  # a stamp 30 or 100 periods ahead: beyond a short gap (EstimatorConfig.bridge_seconds, 20 ms).
        # (A stamp a few periods ahead is a short gap by design, accepted and bridged: a PC's log has them.)
        s["t"] = last_t + period * rng.choice([30.0, 100.0])
    elif kind == 7:  # time going back, or standing still
        s["t"] = last_t - period * rng.choice([0.0, 1.0, 500.0])
    elif kind == 8:
        s["t"] = None  # missing in a timed stream
    elif kind == 9:
        s["t"] = "abc" if rng.random() < 0.5 else [last_t + period]
    elif kind == 10:
        s[name] = {"value": s[name]}
    elif kind == 11:
        s[name] = [0.0, [1.0, 2.0]] + [0.0] * 5  # ragged
    elif kind == 12:
        s[name] = s[name][:-1] if rng.random() < 0.5 else s[name].reshape(-1, 1)
    else:  # a missing input, unless the estimator may go without it (kalman_fusion's sensors)
        s[name] = "fast" if name in optional else rng.choice([None, "fast"])
    return s


def run(est, samples, mode_raise):
    """(outputs, statuses) of one run; a rejected call in raise mode gives (None, 'raised')."""
    out, statuses = [], []
    for s in samples:
        try:
            f = est.estimate_tip_force(**s)
        except EstimatorInputError as err:
            assert mode_raise, f"hold mode raised: {err}"
            assert isinstance(err, ValueError)
            out.append(None)
            statuses.append("raised")
            continue
        out.append(f)
        statuses.append(est.last_status)
    return out, statuses


def check_floor(make, robot, needs, good, rng, period, optional=()):
    """make(mode) -> a fresh estimator. Both modes: the run with bad samples (a quarter of the calls)
    against the clean one; returns (the number of calls made, the clean run's statuses)."""
    clean, clean_status = run(make("raise"), good, True)
    assert EstimatorStatus.OK in clean_status  # the clean run does get going
    calls = 0
    for mode in ("raise", "hold"):
        samples, is_good, k, last_t = [], [], 0, None
        while k < len(good):
            if last_t is not None and rng.random() < 0.25:
                samples.append(bad_sample(rng, robot, needs, good[k], last_t, period, optional))
                is_good.append(False)
            else:
                samples.append(good[k])
                is_good.append(True)
                last_t = good[k]["t"]
                k += 1
        out, statuses = run(make(mode), samples, mode == "raise")
        calls += len(samples)
        last_good, k = np.zeros(3), 0
        for i, (f, status) in enumerate(zip(out, statuses)):
            if is_good[i]:
                assert status == clean_status[k], (mode, i, status, clean_status[k])
                np.testing.assert_array_equal(f, clean[k])  # exactly: the bad samples left no trace
                k += 1
            elif mode == "raise":
                assert status == "raised", (i, samples[i])
            else:
                assert status is EstimatorStatus.INPUT_REJECTED, (i, samples[i])
                np.testing.assert_array_equal(f, last_good)  # the last good estimate, held
            if f is not None:
                beyond = not f @ f <= BOUND**2
                assert beyond == (status is EstimatorStatus.FORCE_OUT_OF_RANGE), (mode, i, f, status)
                if status not in (EstimatorStatus.INPUT_REJECTED, EstimatorStatus.FORCE_OUT_OF_RANGE):
                    last_good = f
    return calls, clean_status


@pytest.mark.filterwarnings("error::RuntimeWarning")  # no numpy overflow warning escapes on absurd values
def test_floor_no_ok_garbage_and_rejected_samples_leave_no_trace(panda):
    rng = np.random.default_rng(17)
    good = stream(panda, 1340)
    # Two believable but huge loads after the tare window: accepted samples whose estimate is beyond
    # the bound. Both runs hold them; they must come out "force out of range", never "ok".
    for k in (700, 701, 1100):
        good[k] = dict(good[k], base_wrench=good[k]["base_wrench"] + np.array([0, 0, 800.0, 0, 0, 0]))
    calls = 0
    for method in NEEDS:
        def make(mode):
            return TipForceEstimator.analytic(panda, method, call_hz=HZ, on_bad_input=mode, encoder_resolution=0.0,
                                             **EXACT_MODEL)
        n, clean_status = check_floor(make, panda, NEEDS[method], good, rng, 1.0 / HZ,
                                      optional=TIP_FORCE_METHODS[method].reads if TIP_FORCE_METHODS[method].any_of else ())
        calls += n
        if method == "base-wrench":  # the loads above are base-wrench inputs
            assert [clean_status[k] for k in (700, 701, 1100)] == [EstimatorStatus.FORCE_OUT_OF_RANGE] * 3
    assert calls >= 10_000


@pytest.mark.slow
def test_floor_learned_model(tmp_path, panda):
    """The same floor for a tiny residual-basewrench model (tare + window + LSTM), called at twice its
    training rate; training and compiling take most of its 10-20 s."""
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.learn import TrainConfig, train_model

    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=4, n_samples=120, record_hz=100.0,
                                             noise=0.002, seed=2))
    train_model(ds, "residual-basewrench", tmp_path / "m", TrainConfig(max_epochs=1, max_batches_per_epoch=3,
                                                                       progress=False))
    hz = 200.0
    def make(mode):
        return TipForceEstimator.load(tmp_path / "m", call_hz=hz, runtime="numba", on_bad_input=mode)
    calls, _ = check_floor(make, panda, ("q", "qd", "base_wrench"), stream(panda, 300, hz=hz, seed=3),
                           np.random.default_rng(5), 1.0 / hz)
    assert calls > 600


# ----------------------------------------------------------------- the cases
def test_a_recording_at_another_rate_is_refused(panda):
    """The README's estimator (call_hz=1000) fed a 100 Hz recording with its true t erred 10 N, 'ok'."""
    good = stream(panda, 5, hz=100.0)
    est = TipForceEstimator.analytic(panda, "base-wrench", call_hz=1000.0, encoder_resolution=0.0)
    est.estimate_tip_force(**{k: good[0][k] for k in ("q", "qd", "base_wrench", "t")})
    with pytest.raises(EstimatorInputError, match=r"steps 0\.01 s .* call_hz=1000 expects 0\.001 s"):
        est.estimate_tip_force(**{k: good[1][k] for k in ("q", "qd", "base_wrench", "t")})
    # Stamps jittering by up to 0.5 ms about the robot's clock (EstimatorConfig.stamp_jitter) pass, steps
    # of 0.1-2 ms included. A short gap in a stream at its rate is accepted, its lost ticks bridged; a step
    # beyond bridge_seconds is refused, and the stream goes on when the next stamp lies one period after it.
    est = TipForceEstimator.analytic(panda, "torques-pinv", call_hz=1000.0, encoder_resolution=0.0)
    s = {k: good[0][k] for k in ("q", "qd", "tau_J")}
    for k, e in enumerate((0.0, 4e-4, -4e-4, 4.5e-4, -3e-4)):
        est.estimate_tip_force(**s, t=k * 1e-3 + e)
    est.estimate_tip_force(**s, t=10e-3)  # ticks 5-9 lost: a short gap
    assert est._gate.lost_ticks == 5 and est.last_status is not EstimatorStatus.INPUT_REJECTED
    with pytest.raises(EstimatorInputError, match=r"steps 0\.04 s from the last accepted sample"):
        est.estimate_tip_force(**s, t=50e-3)  # 39 ticks lost: a long gap, or a stray stamp?
    est.estimate_tip_force(**s, t=51e-3)  # one period after it: the gap's end
    assert est._gate.lost_ticks == 40 and est.last_status is not EstimatorStatus.INPUT_REJECTED


def test_one_absurd_velocity_leaves_the_observer_untouched(panda):
    """qd = 1e150 once left the momentum observer wrong for seconds; now it is rejected before it."""
    good = stream(panda, 400)
    def estimates(bad_at=None):
        est = TipForceEstimator.analytic(panda, "momentum-observer", call_hz=HZ, on_bad_input="hold", encoder_resolution=0.0)
        out = []
        for k, s in enumerate(good):
            if k == bad_at:
                est.estimate_tip_force(**dict(s, qd=np.full(7, 1e150)))
                assert est.last_status is EstimatorStatus.INPUT_REJECTED and "qd[0]" in est.last_rejection
            out.append(est.estimate_tip_force(**s))
        return np.stack(out)
    np.testing.assert_array_equal(estimates(bad_at=150), estimates())


def test_time_cannot_be_bypassed_by_a_missing_t(panda):
    """t = 10, then None, then 5 was accepted: the None skipped the ordering check."""
    s = {k: v for k, v in stream(panda, 1)[0].items() if k != "t"}
    est = TipForceEstimator.analytic(panda, "torques-pinv", call_hz=HZ, encoder_resolution=0.0)
    est.estimate_tip_force(**s, t=10.0)
    with pytest.raises(EstimatorInputError, match="t is missing"):
        est.estimate_tip_force(**s)
    with pytest.raises(EstimatorInputError, match="time must increase"):
        est.estimate_tip_force(**s, t=5.0)
    est.reset()  # a new stream may be untimed
    est.estimate_tip_force(**s)
    assert est.last_status is EstimatorStatus.WARMING_UP


@pytest.mark.filterwarnings("ignore::hybrid_dyn.analytic.robot.JointLimitWarning")  # torques: q past a limit
def test_the_stated_margins(panda):
    """q may sit up to 0.1 rad past a limit, |qd| up to 1.5x the velocity limit, |tau_J| up to 1.5x the
    effort limit; a hair beyond each is rejected."""
    s = {k: v for k, v in stream(panda, 1)[0].items() if k != "t"}
    cases = [("q", 6, panda.q_upper[6] + 0.1), ("qd", 4, 1.5 * panda.spec.max_velocity[4]),
             ("tau_J", 0, -1.5 * panda.model.effortLimit[0])]
    for name, j, edge in cases:
        for value, ok in ((edge - 1e-9 * np.sign(edge), True), (edge + 1e-6 * np.sign(edge), False)):
            est = TipForceEstimator.analytic(panda, "torques-pinv", call_hz=HZ, on_bad_input="hold", encoder_resolution=0.0)
            x = s[name].copy()
            x[j] = value
            est.estimate_tip_force(**dict(s, **{name: x}))
            assert (est.last_status is not EstimatorStatus.INPUT_REJECTED) == ok, (name, value, est.last_rejection)


def test_a_force_beyond_the_bound_is_out_of_range_and_not_held(panda):
    good = stream(panda, 60)
    est = TipForceEstimator.analytic(panda, "base-wrench", call_hz=HZ, tare_seconds=0.0, on_bad_input="hold", encoder_resolution=0.0)
    for s in good[:-2]:  # past the qdd filter's settling
        f1 = est.estimate_tip_force(**s)
    assert est.last_status is EstimatorStatus.OK
    w = good[-2]["base_wrench"] + np.array([0, 0, 700.0, 0, 0, 0])  # 870 N: inside the input bound (1014 N)
    f2 = est.estimate_tip_force(**dict(good[-2], base_wrench=w))
    assert est.last_status is EstimatorStatus.FORCE_OUT_OF_RANGE and est.last_status.value == "force out of range"
    assert np.linalg.norm(f2) > BOUND
    held = est.estimate_tip_force(**dict(good[-1], t="abc"))
    assert est.last_status is EstimatorStatus.INPUT_REJECTED
    np.testing.assert_array_equal(held, f1)  # the last estimate within the bound


def test_any_numeric_layout_gives_what_float64_arrays_give(panda):
    """The compiled gate takes float64 1-D contiguous arrays; every other numeric form of the same values
    (a list, a read-only, strided or big-endian array, a kalman_fusion call without one sensor) goes the
    converting path and must give exactly the same estimates and statuses."""
    def variants(x):
        ro = x.copy()
        ro.flags.writeable = False
        return [list(x), ro, np.repeat(x, 2)[::2], x.astype(">f8")]

    good = stream(panda, 6)
    for method in ("base-wrench", "kalman-fusion"):
        for v in range(4):
            plain = TipForceEstimator.analytic(panda, method, call_hz=HZ, tare_seconds=0.0, encoder_resolution=0.0)
            other = TipForceEstimator.analytic(panda, method, call_hz=HZ, tare_seconds=0.0, encoder_resolution=0.0)
            for k, s in enumerate(good):
                if method == "kalman-fusion" and k == 3:
                    s = dict(s, tau_J=None)
                odd = {n: (variants(x)[v] if isinstance(x, np.ndarray) else x) for n, x in s.items()}
                np.testing.assert_array_equal(other.estimate_tip_force(**odd), plain.estimate_tip_force(**s))
                assert other.last_status is plain.last_status


# ------------------------------------------------- statuses that tell the truth
OK_TOLERANCE = 1.0  # N: no "ok" call may err more, once a contact has lasted the method's settling time (the
# issue's check is 2 N; the worst seen here is 0.65 N, the noise the rule allows on these streams)
OK_RMS = 0.3  # N: nor may the "ok" calls' RMS error (0.22 N at most here)
def settle_calls(est) -> int:
    """The method's longest settling time [calls], over the sensor sets it may run on."""
    stream = est._stream
    if est.spec.any_of:
        return max(stream.settle_calls(s) for s in (("base_wrench",), ("tau_J",), ("base_wrench", "tau_J")))
    return stream.settle_calls(est.spec.reads)


def pattern_run(robot, method, pattern, rng):
    """One stream pattern fed to a fresh estimator with its defaults: (statuses, errors [N], settle calls,
    calls since the contact began or since the stream resumed, whichever is later, per call)."""
    hz = HZ
    samples, force = contact_stream(robot, 1700, seed=int(rng.integers(1 << 30)))
    est = TipForceEstimator.analytic(robot, method, call_hz=hz, on_bad_input="hold", encoder_resolution=0.0,
                                     **EXACT_MODEL)
    reads = est.spec.reads
    statuses, errors, since = [], [], []
    gap = (int(rng.integers(1100, 1400)), int(rng.integers(2, 6))) if pattern == "gap" else None
    phase = int(rng.integers(2))
    last_event = -10**9
    k = 0
    while k < len(samples):
        s = {name: samples[k][name] for name in ("q", "qd", "t") + reads}
        if gap and gap[0] <= k < gap[0] + gap[1]:
            k += 1
            continue  # lost samples
        if gap and k == gap[0] + gap[1]:
            last_event = k + 1  # the sample after the refused one resumes
        if pattern == "alternating" or (pattern == "alternating-after-window" and k >= 600):
            s["base_wrench" if (k + phase) % 2 else "tau_J"] = None
        if pattern == "late-base" and samples[k]["t"] < 0.7:
            s["base_wrench"] = None
        if pattern == "untimed-half-rate":  # a 500 Hz recording (every other sample) into call_hz=1000, no t
            if k % 2:
                k += 1
                continue
            s["t"] = None
        if pattern == "untimed":
            s["t"] = None
        f = est.estimate_tip_force(**s)
        statuses.append(est.last_status)
        errors.append(float(np.linalg.norm(f - force[k])))
        contact_start = int(CONTACT_AT * hz)
        since.append(k - max(contact_start, last_event) if k >= contact_start else 10**9)
        k += 1
    # A stream whose every window was refused (a wrong rate's qdd can look like a held force) never settles.
    settle = settle_calls(est) if est.bandwidth is not None else None
    return statuses, np.array(errors), settle, np.array(since)


# Every registered method; one whose call may bring either sensor (any_of) meets the alternating ones too.
PATTERNS = {m.name: ("untimed", "gap", "untimed-half-rate")
            + (("alternating", "alternating-after-window", "late-base") if m.any_of else ())
            for m in TIP_FORCE_METHODS.values()}


@pytest.mark.parametrize("method", list(PATTERNS))
def test_no_ok_call_errs_once_the_contact_has_settled(method, panda):
    """The issue's stream patterns, randomized (gap place and length, alternation phase, noise draws):
    every "ok" call errs at most OK_TOLERANCE once the contact (or the resumed stream) has lasted the
    method's settling time; a stream at half the rate without t is never "ok"; the right rate is."""
    rng = np.random.default_rng(27)
    for pattern in PATTERNS[method]:
        for _ in range(2):
            statuses, errors, settle, since = pattern_run(panda, method, pattern, rng)
            ok = np.array([s is EstimatorStatus.OK for s in statuses])
            if pattern == "untimed-half-rate":
                assert not ok.any(), (method, pattern)
                assert statuses[-1] is EstimatorStatus.WRONG_RATE
                continue
            assert ok[-200:].all(), (method, pattern, statuses[-1])  # it does get going, and says so
            judged = ok & (since >= settle)
            worst = errors[judged].max()
            assert worst <= OK_TOLERANCE, (method, pattern, worst, int(np.argmax(np.where(judged, errors, 0))))
            assert np.sqrt(np.mean(errors[judged] ** 2)) <= OK_RMS, (method, pattern)
            assert EstimatorStatus.WRONG_RATE not in statuses


def test_a_late_base_sensor_never_tares_over_a_contact(panda):
    """tau_J from the start, the base sensor from 0.7 s, the contact from 1.0 s (the issue's case: a
    permanent 6 N error once): the tare that started at 0.7 s starts over when the torques see the
    contact, so the base sensor is not used; the estimate stays right, on the torques."""
    samples, force = contact_stream(panda, 2500, seed=5)
    est = TipForceEstimator.analytic(panda, "kalman-fusion", call_hz=HZ, encoder_resolution=0.0, **EXACT_MODEL)
    out = []
    for s in samples:
        out.append(est.estimate_tip_force(**dict(s, base_wrench=None if s["t"] < 0.7 else s["base_wrench"])))
    assert not est._tare.done and est._tare.count < 50  # never finished over the contact
    assert est.last_status is EstimatorStatus.OK
    assert np.linalg.norm(out[-1] - force[-1]) < 0.5


def test_a_call_the_method_cannot_estimate_from_says_so(panda):
    """kalman-fusion with the torques for the window, then only a base sensor that is not yet tared:
    "no usable sensor" (not a stale "ok") until its tare is done (500 base calls), then warming up, then
    ok on the base sensor (the contact comes at 1.3 s, after that tare)."""
    samples, force = contact_stream(panda, 1600, seed=6, contact_at=1.3)
    est = TipForceEstimator.analytic(panda, "kalman-fusion", call_hz=HZ, encoder_resolution=0.0, **EXACT_MODEL)
    statuses, out = [], []
    for k, s in enumerate(samples):
        out.append(est.estimate_tip_force(**dict(s, base_wrench=None) if k < 500 else dict(s, tau_J=None)))
        statuses.append(est.last_status)
    assert set(statuses[506:999]) == {EstimatorStatus.NO_SENSOR}  # the torques left (5 calls bridged)
    assert statuses[1000] is EstimatorStatus.WARMING_UP and statuses[-1] is EstimatorStatus.OK
    assert np.linalg.norm(out[-1] - force[-1]) < 1.0
