"""The joint-torque model inside the estimator: what a measured tau_J holds beyond the rigid body.

A joint-torque method explains tau_J - ID(q, qd, qdd) by a force at the tool. On a real arm tau_J also
carries the joints' friction and, on some arms, a spring (Baxter's shoulder): left in, they read as force
(tens of newtons on the KUKA and Baxter logs). An identified parameter file (``identify/identified_model.py``)
holds all three: the inertials go into the :class:`Robot` (``load_robot(params=...)``), and the terms beyond
the rigid body into :class:`JointTorqueModel`, which the estimator takes from tau_J before any method sees
it, as the identification added them:

    tau_J = M(q) qdd + C(q, qd) qd + g(q) + tau_f(qd) + tau_spring(q) [+ a learned residual] - J_v^T F

A hybrid adds a learned residual (q, qd, qdd) -> tau [Nm] on top (``correction``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..description import RobotDescriptionError


@dataclass
class JointTorqueModel:
    """The torque model's terms beyond the rigid body, for one robot.

    name: what it is, as the reports name it ("identified+friction+springs", ...; one word, as a csv key).
    friction: qd [rad/s] (nv,) -> friction torque [Nm] (nv,), or None.
    springs: joint name -> [k_lin, k_sin, k_cos] (``identify/extra_terms.py``).
    correction: a learned residual (q, qd, qdd) -> [Nm] (nv,), or None; reads qdd [rad/s^2].
    digest: sha256 of the parameter file it was read from (a calibration names it), or None."""

    name: str
    joint_names: tuple
    friction: Callable | None = None
    springs: dict | None = None
    correction: Callable | None = None
    digest: str | None = None

    @property
    def needs_qdd(self) -> bool:
        return self.correction is not None

    def extra_torque(self, q, qd, qdd=None) -> np.ndarray:
        """The terms beyond the rigid body at one sample (nv,) [Nm]: what tau_J carries that no force does."""
        from ..identify.identified_model import spring_torque

        out = np.zeros(len(self.joint_names))
        if self.friction is not None:
            out += self.friction(qd)
        if self.springs:
            out += spring_torque(self.springs, self.joint_names, q)
        if self.correction is not None:
            out += self.correction(q, qd, qdd)
        return out

    @classmethod
    def from_params(cls, params, robot) -> "JointTorqueModel | None":
        """The terms of an identified parameter file (its friction and declared springs), or None when
        ``params`` is none (a set name, a nominal parameter file: rigid body only). The file must be for
        ``robot``'s arm."""
        from ..identify.identified_model import friction_from_dict, read_identified_file, springs_from_dict

        found = read_identified_file(params)
        if found is None:
            return None
        doc, digest = found
        if str(doc.get("robot", "")) != robot.name:  # the variant too: a tool's inertials are in the file's last body
            raise RobotDescriptionError(f"{params} was identified for robot {doc.get('robot')!r}, not "
                                        f"{robot.name!r}: pass the file identified on this arm (with this tool)")
        springs = springs_from_dict(doc, robot.joint_names, str(params))
        name = "identified+friction" + ("+springs" if springs else "")
        return cls(name, tuple(robot.joint_names), friction_from_dict(doc["friction"], str(params)), springs,
                   digest=digest)


    def with_residual_gp(self, model_dir, robot) -> "JointTorqueModel":
        """This model plus a residual GP (``hybrid-dyn bench``'s ``gp-residual-identified``, ``learn/gp_residual.py``)
        fitted on the same identified file: its correction is added to the terms beyond the rigid body. A GP
        fitted on another parameter file is refused."""
        from ..learn.gp_residual import load_gp_residual

        gp = load_gp_residual(model_dir, robot=robot)
        if gp.config["prior"]["params_sha256"] != self.digest:
            raise RobotDescriptionError(f"the residual GP in {model_dir} was fitted on another parameter file "
                                        f"({gp.config['prior']['params']}): pass the file it corrects")
        residual = gp.residual
        nv = len(self.joint_names)
        x = np.empty((1, 3 * nv))

        def correction(q, qd, qdd):
            x[0, :nv], x[0, nv:2 * nv], x[0, 2 * nv:] = q, qd, (0.0 if qdd is None else qdd)
            return residual.predict_rows(x)[0]

        fingerprint = str(gp.config.get("fingerprint", ""))[:16]
        return JointTorqueModel(self.name + "+gp", self.joint_names, self.friction, self.springs, correction,
                                digest=f"{self.digest}+gp:{fingerprint}")


__all__ = ["JointTorqueModel"]
