"""Reference trajectories: random goals, RRT-Connect paths, jerk-limited timing.

The detail (what it computes, the equations, why each choice): docs/design/sim.md, section ``sim/trajectories.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ruckig

from ..errors import HybridDynError

_TRAPPED, _ADVANCED, _REACHED = 0, 1, 2


class PlanningError(HybridDynError, RuntimeError):
    """No valid goal or path was found within the iteration budget."""


def motion_valid(a: np.ndarray, b: np.ndarray, is_valid, resolution: float = 0.02) -> bool:
    """True when the straight joint-space segment a -> b is valid at ``resolution`` [rad] steps."""
    n = max(1, int(np.ceil(np.max(np.abs(b - a)) / resolution)))
    for s in np.linspace(0.0, 1.0, n + 1)[1:]:
        if not is_valid(a + s * (b - a)):
            return False
    return True


class _Tree:
    def __init__(self, root: np.ndarray, capacity: int):
        self.nodes = np.empty((capacity, len(root)))
        self.parent = np.empty(capacity, dtype=np.int64)
        self.nodes[0], self.parent[0], self.n = root, -1, 1

    def add(self, q, parent) -> int:
        self.nodes[self.n], self.parent[self.n] = q, parent
        self.n += 1
        return self.n - 1

    def nearest(self, q) -> int:
        return int(np.argmin(np.sum((self.nodes[: self.n] - q) ** 2, axis=1)))

    def branch(self, i) -> list:
        out = []
        while i >= 0:
            out.append(self.nodes[i].copy())
            i = self.parent[i]
        return out  # from node i back to the root


def rrt_connect(start, goal, is_valid, lower, upper, rng: np.random.Generator, step: float = 0.3,
                max_iterations: int = 3000, resolution: float = 0.02) -> list[np.ndarray] | None:
    """A collision-free joint-space path start -> goal as a list of waypoints, or None.

    ``step`` [rad] is the largest extension (Euclidean in joint space);
    ``resolution`` [rad] the per-joint step of segment checks.
    """
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    if motion_valid(start, goal, is_valid, resolution):
        return [start, goal]
    trees = [_Tree(start, max_iterations + 2), _Tree(goal, max_iterations + 2)]
    start_tree = trees[0]

    def extend(tree, target):
        i = tree.nearest(target)
        near = tree.nodes[i]
        d = target - near
        dist = np.linalg.norm(d)
        new = target if dist <= step else near + d * (step / dist)
        if not motion_valid(near, new, is_valid, resolution):
            return _TRAPPED, -1
        j = tree.add(new, i)
        return (_REACHED if dist <= step else _ADVANCED), j

    for _ in range(max_iterations):
        a, b = trees
        status, ja = extend(a, rng.uniform(lower, upper))
        if status != _TRAPPED:
            target = a.nodes[ja].copy()
            while True:
                status_b, jb = extend(b, target)
                if status_b != _ADVANCED:
                    break
            if status_b == _REACHED:
                # a's root .. node ja == node jb .. b's root; orient it start -> goal.
                path = a.branch(ja)[::-1] + b.branch(jb)[1:]
                return path if a is start_tree else path[::-1]
        trees.reverse()
    return None


def shortcut(path: list[np.ndarray], is_valid, rng: np.random.Generator, attempts: int = 50,
             resolution: float = 0.02) -> list[np.ndarray]:
    """Random shortcutting: replace the stretch between two waypoints by a straight valid segment."""
    path = list(path)
    for _ in range(attempts):
        if len(path) <= 2:
            break
        i, j = sorted(rng.choice(len(path), 2, replace=False))
        if j - i >= 2 and motion_valid(path[i], path[j], is_valid, resolution):
            path = path[: i + 1] + path[j:]
    return path


@dataclass
class Reference:
    """A joint reference sampled every ``dt`` [s]: q [rad], qd [rad/s], qdd [rad/s^2], each (T, nv)."""

    dt: float
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    n_trajectories: int = 0

    @property
    def t(self) -> np.ndarray:
        return np.arange(len(self.q)) * self.dt

    def __len__(self) -> int:
        return len(self.q)


def time_segment(a, b, vmax, amax, jmax, dt: float):
    """Rest-to-rest jerk-limited motion along the straight segment a -> b, sampled every ``dt``.

    Returns (q, qd, qdd), each (n, nv). The motion is timed as a 1-DoF ruckig
    problem on the arc length s along the unit direction d = (b - a)/|b - a|,
    with the tightest per-joint limits projected on d (v_s = min_j vmax_j/|d_j|,
    and so on), so q = a + s d stays exactly on the checked segment and every
    joint stays within its own limits. The samples cover [0, duration), a whole
    number of steps; the end state (b at rest) is the first sample of whatever
    follows.
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    length = float(np.linalg.norm(b - a))
    if length == 0.0:
        return (np.zeros((0, len(a))),) * 3
    d = (b - a) / length
    with np.errstate(divide="ignore"):
        scale = np.where(np.abs(d) > 0, 1.0 / np.abs(d), np.inf)
    otg = ruckig.Ruckig(1, dt)
    inp = ruckig.InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [length]
    inp.current_velocity = inp.current_acceleration = inp.target_velocity = inp.target_acceleration = [0.0]
    inp.max_velocity = [float(np.min(np.asarray(vmax) * scale))]
    inp.max_acceleration = [float(np.min(np.asarray(amax) * scale))]
    inp.max_jerk = [float(np.min(np.asarray(jmax) * scale))]
    inp.duration_discretization = ruckig.DurationDiscretization.Discrete  # duration = whole steps
    traj = ruckig.Trajectory(1)
    result = otg.calculate(inp, traj)
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise PlanningError(f"ruckig could not time the segment ({result})")
    n = int(round(traj.duration / dt))
    path = np.array([traj.at_time(k * dt) for k in range(n)]).reshape(n, 3)  # s, s', s''
    return a + path[:, :1] * d, path[:, 1:2] * d, path[:, 2:3] * d


def random_goal(robot, rng, is_valid, margin: float, tries: int = 1000) -> np.ndarray:
    """A goal uniform within the joint limits less ``margin`` [rad], collision-free."""
    lo, hi = robot.q_lower + margin, robot.q_upper - margin
    for _ in range(tries):
        q = rng.uniform(lo, hi)
        if is_valid is None or is_valid(q):
            return q
    raise PlanningError(f"no collision-free goal in {tries} draws")


def random_reference(robot, rng: np.random.Generator, n_trajectories: int, dt: float = 1e-3,
                     speed_scale=(0.2, 0.6), margin: float = 0.1, standstill: float = 1.0,
                     is_valid=None, start=None) -> Reference:
    """One instance's reference: standstill, then n (trajectory, standstill) pairs.

    Starts at ``start`` (default: the robot's home pose). If no path to a goal is
    found, a new goal is drawn (as in the seed).
    """
    nv = robot.nv
    vmax, amax, jmax = (np.asarray(x, float) for x in (robot.spec.max_velocity, robot.spec.max_acceleration,
                                                         robot.spec.max_jerk))
    q = np.asarray(robot.spec.home if start is None else start, float)
    n_still = int(round(standstill / dt))
    zeros = np.zeros((n_still, nv))
    parts = [(np.tile(q, (n_still, 1)), zeros, zeros)]
    lo, hi = robot.q_lower + margin, robot.q_upper - margin
    for _ in range(n_trajectories):
        for _attempt in range(100):
            goal = random_goal(robot, rng, is_valid, margin)
            path = [q, goal] if is_valid is None else rrt_connect(q, goal, is_valid, lo, hi, rng)
            if path is not None:
                break
        else:
            raise PlanningError("no path found to 100 successive random goals")
        if is_valid is not None:
            path = shortcut(path, is_valid, rng)
        s = rng.uniform(*speed_scale)
        for a, b in zip(path[:-1], path[1:]):
            parts.append(time_segment(a, b, s * vmax, s * amax, s * jmax, dt))
        q = path[-1]
        parts.append((np.tile(q, (n_still, 1)), zeros, zeros))
    return Reference(dt, *(np.concatenate([p[i] for p in parts]) for i in range(3)), n_trajectories=n_trajectories)
