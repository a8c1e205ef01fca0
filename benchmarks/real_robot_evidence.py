"""What the real KUKA and Baxter logs say about their robots' descriptions.

The logs name no joints, no arm and no axis convention. This script prints the evidence that
decided each choice in ``robots/kuka-lwr.toml``, ``robots/baxter.toml`` and the import specs:

- **column order**: each column's range against the description's joint limits;
- **which arm / which axis signs**: the nominal model's gravity torques against the logged
  torques on the slow samples (|qd| and |qdd| small, so the torque is gravity and friction);
- **the whole physics**: ordinary least squares of the joint-torque regressor plus viscous,
  Coulomb and offset friction per joint (and the declared extra terms), fitted on the first 8
  trajectories and scored on the last 2, per joint, with the base regressor's condition number;
- **what the physics leaves**: that fit's error per trajectory (leave one trajectory out), and
  whether a function of the state explains the residual.

    python benchmarks/real_robot_evidence.py [--robot baxter|kuka-lwr] [--logs DIR]

Reads the .mat logs directly (scipy), not through the import spec, so that it can try column
orders the spec does not use. Prints only; nothing is written.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
import scipy.io

import hybrid_dyn as hd
from hybrid_dyn.analytic import JointLimitWarning
from hybrid_dyn.data.derivatives import DerivativeFilter, differentiate
from hybrid_dyn.description.locations import robots_dir
from hybrid_dyn.identify.extra_terms import extra_regressor
from hybrid_dyn.identify.regressor import base_parameters, full_regressor

LOGS = {"baxter": ("BaxterDirectDynamics.mat", "baxtertraj", 100.4), "kuka-lwr": ("KukaDirectDynamics.mat", "kukatraj", 100.0)}
# Column orders to try: file column (0-based) for each joint of the robot's chain order.
ORDERS = {
    "baxter": {"file order (s0 s1 e0 e1 w0 w1 w2)": [0, 1, 2, 3, 4, 5, 6],
               "alphabetical (e0 e1 s0 s1 w0 w1 w2)": [2, 3, 0, 1, 4, 5, 6]},
    "kuka-lwr": {"file order (A1..A7)": [0, 1, 2, 3, 4, 5, 6]},
}
# The KUKA log names its robot only as "KUKA LWR" (its source's README: "Kuka LWR iowa", likely iiwa):
# the candidate kinematics, base-to-A2, A2-A4, A4-A6, A6-flange [m], each from its maker's datasheet.
KUKA_CHAINS = {"LWR 4+": (0.3105, 0.4, 0.39, 0.078), "LBR iiwa 7 R800": (0.34, 0.4, 0.4, 0.126),
               "LBR iiwa 14 R820": (0.36, 0.42, 0.4, 0.126)}
SLOW_QD, SLOW_QDD = 0.05, 0.1  # rad/s, rad/s^2: a sample this slow on every joint is quasi-static


def load_log(robot: str, logs: Path):
    fname, var, rate = LOGS[robot]
    mat = scipy.io.loadmat(logs / fname)
    trajs = []
    for i in range(1, 11):
        x = mat[f"{var}{i}"]
        t = np.arange(len(x)) / rate
        qdd = differentiate(x[:, 7:14], t, DerivativeFilter("butter", cutoff_hz=5.0, order=4))
        trajs.append((x[:, 0:7], x[:, 7:14], qdd, x[:, 14:21]))
    return trajs


def variant_robots(robot: str):
    """The description, and for Baxter the other arm too (the same TOML with left and right swapped)."""
    out = {robot: hd.load_robot(robot)}
    if robot == "baxter":
        text = (robots_dir() / "baxter.toml").read_text()
        swapped = text.replace("left_", "@@").replace("right_", "left_").replace("@@", "right_")
        swapped = swapped.replace("l_gripper", "##").replace("r_gripper", "l_gripper").replace("##", "r_gripper")
        tmp = Path(tempfile.mkdtemp()) / "baxter-right.toml"
        tmp.write_text(swapped)
        out = {"left arm": out[robot], "right arm": hd.load_robot(str(tmp))}
    return out


def alternating_chain_urdf(lengths, signs) -> str:
    """A 7-joint arm with axes z, y, z, y, z, y, z (times ``signs``) stacked along z at q = 0 (KUKA's
    LWR and iiwa layout), unit masses mid-segment: enough for a least-squares fit, which re-fits every
    inertial; ``lengths`` as in KUKA_CHAINS."""
    d0, d1, d2, d3 = lengths
    z = [d0 - 0.2, 0.2, d1 - 0.2, 0.2, d2 - 0.2, 0.2, 0.0]  # A1 origin (irrelevant: vertical axis), then A2..A7
    axes = ["0 0 1", "0 1 0"] * 3 + ["0 0 1"]
    links = ['<link name="l0"/>'] + [f'<link name="l{i}"><inertial><mass value="1"/><origin xyz="0 0.01 0.05"/>'
                                     f'<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>'
                                     for i in range(1, 8)]
    joints = [f'<joint name="a{i + 1}" type="revolute"><parent link="l{i}"/><child link="l{i + 1}"/>'
              f'<origin xyz="0 0 {z[i]}"/><axis xyz="{" ".join(str(sg * float(c)) for c in axes[i].split())}"/>'
              f'<limit lower="-3" upper="3" effort="200" velocity="2"/></joint>' for i, sg in enumerate(signs)]
    return f'<robot name="chain">{"".join(links)}{"".join(joints)}' \
           f'<link name="tool"/><joint name="ft" type="fixed"><parent link="l7"/><child link="tool"/>' \
           f'<origin xyz="0 0 {d3}"/></joint></robot>'


def chain_robot(lengths, signs):
    tmp = Path(tempfile.mkdtemp())
    (tmp / "chain.urdf").write_text(alternating_chain_urdf(lengths, signs))
    (tmp / "chain.toml").write_text('name = "chain"\nurdf = "chain.urdf"\ntool_frame = "tool"\n'
                                    'base_sensor_frame = "l0"\n')
    return hd.load_robot(str(tmp / "chain.toml"))


def kuka_hypotheses(trajs) -> None:
    """Which chain and which axis signs fit the log best (OLS, trajectories 9-10 held out)."""
    import itertools

    results = []
    for signs in itertools.product((1, -1), repeat=7):
        if signs[0] < 0:
            continue  # A1's sign only mirrors the whole arm about the vertical: no torque can tell it
        rob = chain_robot(KUKA_CHAINS["LWR 4+"], signs)
        results.append((ols_fit(rob, trajs[:8], trajs[8:], False, n_every=4)[1], signs))
    results.sort()
    print("\n-- axis signs (A1..A7, +: z or y as in the layout), LWR 4+ lengths, the 5 best and the worst of 64:")
    for rmse, signs in results[:5] + results[-1:]:
        print(f"  {signs}: test RMSE {rmse:.3f} Nm")
    best = results[0][1]
    print(f"\n-- chains at the best signs {best}:")
    for name, lengths in KUKA_CHAINS.items():
        per_joint, total, cond = ols_fit(chain_robot(lengths, best), trajs[:8], trajs[8:], False)
        print(f"  {name} {lengths}: test RMSE {total:.3f} Nm, per joint {per_joint} (condition number {cond:.3g})")


def regressor_of(rob, extra: bool):
    """(q, qd, qdd) -> the base regressor of rigid body and friction (+ the declared extra terms)."""
    bp = base_parameters(rob, friction=True)

    def regressor(q, qd, qdd):
        W = bp.reduce(full_regressor(rob, q, qd, qdd, friction=True))
        E = extra_regressor(rob.spec, q, rob.joint_names) if extra else None
        return W if E is None else np.concatenate([W, E], axis=-1)

    return regressor


def least_squares(W: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """OLS coefficients of stacked regressors W (n, nv, p) against torques tau (n, nv)."""
    beta, *_ = np.linalg.lstsq(W.reshape(-1, W.shape[-1]), tau.reshape(-1), rcond=None)
    return beta


def ols_fit(rob, train, test, extra: bool, n_every: int = 1):
    """Test RMSE per joint [Nm] of OLS on the base regressor (+ friction, + the declared extra terms)."""
    regressor = regressor_of(rob, extra)

    def stack(parts):
        q, qd, qdd, tau = (np.concatenate([p[k][::n_every] for p in parts]) for k in range(4))
        return regressor(q, qd, qdd), tau

    Wtr, ttr = stack(train)
    Wte, tte = stack(test)
    beta = least_squares(Wtr, ttr)
    err = (Wte.reshape(-1, Wte.shape[-1]) @ beta).reshape(tte.shape) - tte
    A = Wtr.reshape(-1, Wtr.shape[-1])
    s = np.linalg.svd(A / np.maximum(np.linalg.norm(A, axis=0), 1e-12), compute_uv=False)
    return np.sqrt(np.mean(err ** 2, axis=0)), np.sqrt(np.mean(err ** 2)), s[0] / s[-1]


def residual_structure(rob, parts) -> None:
    """What the physics leaves, per trajectory (each scored by the fit on the other nine), and whether a
    function of the state explains it (least squares on state features, fitted on the residuals of
    trajectories 1-8 and scored on 9-10): if it does not, no correction of (q, qd, qdd) can learn it."""
    print("\n-- what OLS + declared terms leaves, per trajectory (fitted on the other nine), RMSE per joint [Nm]:")
    regressor = regressor_of(rob, extra=True)
    W = [regressor(*p[:3]) for p in parts]  # each trajectory's regressor once, for all the fits below
    tau = [p[3] for p in parts]
    for k, p in enumerate(parts):
        beta = least_squares(np.concatenate(W[:k] + W[k + 1:]), np.concatenate(tau[:k] + tau[k + 1:]))
        err = W[k] @ beta - p[3]
        print(f"  trajectory {k + 1:2d}: |qd| max {np.abs(p[1]).max():.2f} rad/s, |tau| max per joint "
              f"{np.abs(p[3]).max(0).round(1)}; RMSE {np.sqrt(np.mean(err ** 2, axis=0))}")

    def features(q, qd):
        return np.column_stack([np.ones(len(q)), q, np.sin(q), np.cos(q), np.tanh(qd / 0.02), qd])

    beta = least_squares(np.concatenate(W[:8]), np.concatenate(tau[:8]))
    res = [t - w @ beta for w, t in zip(W, tau)]
    X = np.concatenate([features(p[0], p[1]) for p in parts[:8]])
    Xt = np.concatenate([features(p[0], p[1]) for p in parts[8:]])
    rt = np.concatenate(res[8:])
    w, *_ = np.linalg.lstsq(X, np.concatenate(res[:8]), rcond=None)
    print(f"  the residual on trajectories 9-10, RMSE per joint: {np.sqrt(np.mean(rt ** 2, axis=0))} Nm; after "
          f"least squares on {X.shape[1]} state features (q, sin q, cos q, tanh(qd / 0.02), qd) fitted on the "
          f"residuals of 1-8: {np.sqrt(np.mean((rt - Xt @ w) ** 2, axis=0))} Nm")


def main(argv=None) -> int:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", choices=sorted(LOGS), action="append")
    ap.add_argument("--logs", type=Path, default=Path(os.environ.get(
        "HYBRID_DYN_REAL_LOGS", here.parent / "src/hybrid_dyn/resources/real/logs")))
    args = ap.parse_args(argv)
    # Baxter's log touches e1's limit (the column-range line says by how much): one line, not one per sample.
    warnings.simplefilter("ignore", JointLimitWarning)
    np.set_printoptions(precision=3, suppress=True, linewidth=140)
    for robot in args.robot or sorted(LOGS):
        trajs = load_log(robot, args.logs)
        print(f"\n=== {robot}: {sum(len(t[0]) for t in trajs)} samples in {len(trajs)} trajectories ===")
        if robot == "kuka-lwr":
            kuka_hypotheses(trajs)
        robots = variant_robots(robot)
        rob0 = next(iter(robots.values()))
        lo, hi = rob0.q_lower, rob0.q_upper
        for oname, order in ORDERS[robot].items():
            parts = [tuple(a[:, order] for a in tr) for tr in trajs]
            q = np.concatenate([p[0] for p in parts])
            beyond = np.maximum(q.min(0) < lo - 0.02, q.max(0) > hi + 0.02)
            print(f"\n-- columns read as {oname}")
            print(f"  joints whose logged range leaves the limits by > 0.02 rad: "
                  f"{[rob0.joint_names[j] for j in np.flatnonzero(beyond)] or 'none'}")
            for vname, rob in robots.items():
                qs, qds, qdds, taus = (np.concatenate([p[k] for p in parts]) for k in range(4))
                slow = (np.abs(qds).max(1) < SLOW_QD) & (np.abs(qdds).max(1) < SLOW_QDD)
                g = rob.gravity(qs[slow])
                rms_g = np.sqrt(np.mean((g - taus[slow]) ** 2, axis=0))
                print(f"  {vname}: nominal gravity vs logged torque on {slow.sum()} slow samples, RMSE per joint "
                      f"{rms_g} Nm (all {np.sqrt(np.mean((g - taus[slow]) ** 2)):.3f})")
                # An unknown tool: one point mass at the tool frame, fitted on the slow samples (the sprung
                # joints left out of the fit: their residual is the spring's).
                per_kg = np.einsum("nij,i->nj", rob.tip_jacobian(qs[slow])[:, :3], np.array([0.0, 0.0, 9.81]))
                fit_on = [j for j, n in enumerate(rob.joint_names) if n not in rob.spec.springs]
                res = taus[slow] - g
                mass = np.sum(per_kg[:, fit_on] * res[:, fit_on]) / np.sum(per_kg[:, fit_on] ** 2)
                print(f"    + a load at the tool frame fitted on them: {mass:.2f} kg, RMSE per joint "
                      f"{np.sqrt(np.mean((res - mass * per_kg) ** 2, axis=0))} Nm")
                for extra in (False, True):
                    per_joint, total, cond = ols_fit(rob, parts[:8], parts[8:], extra)
                    label = "OLS + declared terms" if extra else "OLS, rigid body + friction"
                    print(f"    {label}: test RMSE {total:.3f} Nm, per joint {per_joint} "
                          f"(trajectories 9-10; condition number {cond:.3g})")
            if oname == next(reversed(ORDERS[robot])):  # the order the import spec uses
                residual_structure(rob0, parts)  # the description itself (Baxter: the left arm)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
