"""Robot logs written here, as a user would bring them: CSV files and their import specs.

- ``sine_log`` / ``write_csv``: a 7-joint sine log with its analytic derivatives (the importer's checks);
- ``write_log``: a 4 s Panda log about its home pose with an import spec (``spec.toml``) beside it.
"""
from pathlib import Path

import numpy as np

NV = 7
FS = 100.0
Q = [f"q{j}" for j in range(1, NV + 1)]
QD = [f"qd{j}" for j in range(1, NV + 1)]
TAU = [f"tau{j}" for j in range(1, NV + 1)]


def sine_log(n=1000, fs=FS, seed=0):
    """A 7-joint sine log and its analytic derivatives: q = c + A sin(w t + p)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    c, a = rng.uniform(-1, 1, NV), rng.uniform(0.3, 1.0, NV)
    w, p = 2 * np.pi * rng.uniform(0.2, 0.5, NV), rng.uniform(0, 2 * np.pi, NV)
    arg = w * t[:, None] + p
    q, qd, qdd = c + a * np.sin(arg), a * w * np.cos(arg), -a * w**2 * np.sin(arg)
    tau = 5.0 * np.sin(arg) + 0.1 * qd  # any torque: the importer passes it through
    return {"t": t, "q": q, "qd": qd, "qdd": qdd, "tau": tau, "peak_qd": a * w, "peak_qdd": a * w**2}


def write_csv(path, log, with_qd=True, rows=None):
    names = ["t"] + Q + (QD if with_qd else []) + TAU
    cols = [log["t"][:, None], log["q"]] + ([log["qd"]] if with_qd else []) + [log["tau"]]
    data = np.concatenate(cols, axis=1)
    lines = [",".join(names)] + [",".join(repr(float(v)) for v in r) for r in data]
    if rows:  # row index -> replacement line text
        for i, text in rows.items():
            lines[1 + i] = text
    Path(path).write_text("\n".join(lines) + "\n")
    return path


CSV_COLUMNS = {"q": Q, "qd": QD, "tau_m": TAU}


HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


def write_log(folder: Path, n: int = 400, hz: float = 100.0) -> Path:
    """A 4 s log of slow sines about the Panda's home pose and torques that are any numbers, as a CSV."""
    t = np.arange(n) / hz
    w = np.linspace(1.0, 2.5, NV)
    q = HOME + 0.3 * np.sin(w * t[:, None])
    qd = 0.3 * w * np.cos(w * t[:, None])
    tau = np.random.default_rng(0).normal(0, 5, (n, NV))
    return _write_log_and_spec(folder, "my-panda", t, q, qd, tau, "seed = 0")


def _write_log_and_spec(folder: Path, name: str, t, q, qd, tau, split: str) -> Path:
    """log.csv (t, q1-7, qd1-7, tau1-7) and its import spec (the bare-flange Panda, 10 blocks, ``split``: the
    lines of its [split] section); returns the spec's path."""
    header = ",".join(["t"] + [f"{k}{j}" for k in ("q", "qd", "tau") for j in range(1, NV + 1)])
    folder.mkdir(parents=True, exist_ok=True)
    np.savetxt(folder / "log.csv", np.column_stack([t, q, qd, tau]), delimiter=",", header=header, comments="",
               fmt="%.17g")
    cols = lambda k: "[" + ", ".join(f'"{k}{j}"' for j in range(1, NV + 1)) + "]"  # noqa: E731
    spec = folder / "spec.toml"
    spec.write_text(f'name = "{name}"\nrobot = "panda"\ntool = "none"\n[source]\nfiles = ["log.csv"]\n'
                    f'[time]\ncolumn = "t"\n[columns]\nq = {cols("q")}\nqd = {cols("qd")}\ntau_m = {cols("tau")}\n'
                    f'[trajectories]\nfrom = "blocks"\nn_blocks = 10\n[split]\n{split}\n')
    return spec


def write_physical_log(folder: Path, name: str, n: int = 600, hz: float = 100.0, dead_torque=None, still_joint=None,
                       still_from=None, noise: float = 0.05) -> Path:
    """A 6 s Panda log (bare flange) about its home pose whose torques obey the nominal model: RNEA + the Gaz
    friction + white noise [Nm], cut into 10 blocks split in time order (the last 2 test), with its import spec.

    The defects a log can hide: ``dead_torque`` (1-based joint): its torque 0 throughout;
    ``still_joint``: that joint never moves; ``still_from`` [s]: every joint stands still from then on.
    """
    from hybrid_dyn.analytic.robot import load_robot

    robot = load_robot("panda[tool=none]")
    t = np.arange(n) / hz
    w = np.linspace(1.0, 2.5, NV)
    q = HOME + 0.3 * np.sin(w * t[:, None])
    qd = 0.3 * w * np.cos(w * t[:, None])
    qdd = -0.3 * w**2 * np.sin(w * t[:, None])
    if still_joint is not None:
        j = still_joint - 1
        q[:, j], qd[:, j], qdd[:, j] = HOME[j], 0.0, 0.0
    if still_from is not None:
        k = int(round(still_from * hz))
        q[k:], qd[k:], qdd[k:] = q[k - 1], 0.0, 0.0
    tau = robot.inverse_dynamics(q, qd, qdd) + robot.spec.friction("gaz2019")(qd)
    tau += np.random.default_rng(0).normal(0, noise, tau.shape)
    if dead_torque is not None:
        tau[:, dead_torque - 1] = 0.0
    return _write_log_and_spec(folder, name, t, q, qd, tau, 'by = "time"')
