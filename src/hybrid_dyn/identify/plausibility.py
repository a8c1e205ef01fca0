"""What identification returns, checked against the robot it claims to describe.

A fit on data that cannot support it (a dead torque channel, a joint that never moves) still returns
numbers: OLS gave bodies of -10.3 kg with a centre of mass 10 m away, and the sigmoid-friction fit put
32 kg on the Panda's 0.65 kg link 2. Physical consistency (``parameters.check_consistency``) does not
catch the second: 32 kg is a possible body, not this robot's. So each identified body is held to bounds
stated from the nominal robot (:class:`PlausibilityBounds`), and :func:`implausible_bodies` names every
body outside them. The identification also says when its data cannot determine the fit
(:func:`fit_warnings`: a joint's range of motion, the base regressor's condition number).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.data_checks import MOTION_THRESHOLDS, range_of_motion_problems
from .parameters import N_BODY_PARAMS, to_urdf_form


@dataclass(frozen=True)
class PlausibilityBounds:
    """Bounds on each identified body (joint j's body: every link rigidly attached to joint j), from the
    nominal robot:

    - mass [kg] within ``[0, mass_factor x nominal + mass_allowance]``: 3x and 2 kg, since published sets of
      one arm differ that much on a light link (the Panda's link 2: 0.65 kg in the URDF, after Gaz et al.
      2019; 2.54 kg in Franka's official set, which the ``mismatch`` plants use) and a tool or payload the
      nominal model lacks adds to the last body; a fit that drew another joint's load onto a body (32 kg on
      link 2) is far beyond;
    - centre of mass [m] within the body's bounding box grown by its length: the box is the hull of the
      points that belong to the body (its joint frame origin, its parent joint's origin, its child joints'
      origins and every frame fixed to it: ``estimators.com_boxes`` with no margin), its length the box's
      diagonal [m], at least ``min_length`` (a wrist body whose joints share an origin has a box of a few cm);
    - inertia about the centre of mass [kg m^2]: each principal moment within ``+-m D^2``, m the body's mass
      and D the grown box's diagonal: no particle of a body inside the grown box is further than D from its
      centre of mass, so no moment of it is larger. Not its sign: a least-squares fit (ols, wls) determines
      only the base parameters, and the bodies it reports (the nominal ones moved by the least change that
      gives those) are often not positive definite on good data; that is ``physically_consistent``, which
      the consistent fits guarantee. Nor the triangle inequality, which Franka's official set breaks on
      body 4 (a fit that recovers a published plant is not absurd).

    A body outside these is not a fit of this robot: a dead channel or a joint that never moves, not noise.
    """

    mass_factor: float = 3.0
    mass_allowance: float = 2.0
    min_length: float = 0.1


PLAUSIBILITY_BOUNDS = PlausibilityBounds()
# Beyond this the base regressor of the data is numerically rank-deficient: a least-squares fit in float64
# keeps fewer than half its 16 digits in its worst direction (a joint that never moves gave 3e19).
CONDITION_WARNING = 1e8


@dataclass(frozen=True)
class BodyBounds:
    """One body's bounds: mass [0, mass_max] kg, centre of mass in the box [lo, hi] m (its joint frame),
    each principal moment about the centre of mass <= mass x diagonal^2 [kg m^2]."""

    joint: str
    mass_max: float
    lo: np.ndarray
    hi: np.ndarray

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(self.hi - self.lo))


def body_bounds(robot, bounds: PlausibilityBounds = PLAUSIBILITY_BOUNDS) -> list[BodyBounds]:
    """Each joint's body bounds, from the nominal ``robot`` (its merged per-joint masses and frames)."""
    from .least_squares import com_boxes

    out = []
    for j, (lo, hi) in enumerate(com_boxes(robot, 0.0)):
        length = max(float(np.linalg.norm(hi - lo)), bounds.min_length)
        nominal = float(robot.model.inertias[j + 1].mass)
        out.append(BodyBounds(robot.joint_names[j], bounds.mass_factor * nominal + bounds.mass_allowance,
                              lo - length, hi + length))
    return out


def implausible_bodies(robot, body_params, bounds: PlausibilityBounds = PLAUSIBILITY_BOUNDS) -> list[str]:
    """One line per identified body outside its bounds (:class:`PlausibilityBounds`); empty: all within.

    body_params: (nv, 10) dynamic parameters about each joint frame (``IdentifiedModel.body_params``).
    """
    out = []
    params = np.asarray(body_params, float).reshape(-1, N_BODY_PARAMS)
    for b, pi in zip(body_bounds(robot, bounds), params):
        m, c, icom = to_urdf_form(pi)
        why = []
        if not (np.isfinite(m) and 0.0 <= m <= b.mass_max):
            why.append(f"mass {m:.3g} kg outside [0, {b.mass_max:.3g}] kg")
        if m > 0 and not (np.all(c >= b.lo) and np.all(c <= b.hi)):
            why.append(f"centre of mass ({', '.join(f'{x:.3g}' for x in c)}) m, {np.linalg.norm(c):.3g} m from the "
                       f"joint, outside its box grown by its length")
        if not m > 0:  # a body of no mass (said above) has no inertia to bound
            out.append(f"body of {b.joint}: " + "; ".join(why))
            continue
        moments = np.linalg.eigvalsh(np.array([[icom[0], icom[1], icom[2]], [icom[1], icom[3], icom[4]],
                                               [icom[2], icom[4], icom[5]]]))
        limit = m * b.diagonal**2
        big = float(np.abs(moments).max())
        if not big <= limit * (1 + 1e-9):
            why.append(f"principal moment {moments[np.argmax(np.abs(moments))]:.3g} kg m^2 beyond +-mass x "
                       f"diagonal^2 = {limit:.3g} kg m^2")
        if why:
            out.append(f"body of {b.joint}: " + "; ".join(why))
    return out


def fit_warnings(q, condition_number: float, joint_names, what: str = "the identification data") -> list[str]:
    """What the data of a fit cannot determine: each joint whose range of motion in ``q`` (N, nv) [rad] is
    under ``MOTION_THRESHOLDS.min_range_rad``, and a base-regressor condition number above
    :data:`CONDITION_WARNING`. One line each."""
    out = range_of_motion_problems(q, joint_names, what, MOTION_THRESHOLDS)
    if not condition_number <= CONDITION_WARNING:
        out.append(f"the base regressor of {what} has condition number {condition_number:.3g}, above "
                   f"{CONDITION_WARNING:.0e}: some base parameters are not determined by the data")
    return out
