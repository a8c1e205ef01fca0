"""Parameter sets: per-link inertials (JSON) and the Gaz et al. joint friction law."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .physical_checks import inertial_problems
from .base import RobotDescriptionError


@dataclass(frozen=True)
class LinkInertial:
    """Inertial parameters of one URDF link.

    mass [kg]; com [m] in the link frame; inertia [kg m^2] about the COM with
    axes parallel to the link frame, ordered (xx, xy, xz, yy, yz, zz).
    ``None`` in com keeps the URDF's value (not identifiable, e.g. Gaz link-1 c_z).
    """

    name: str
    mass: float
    com: tuple
    inertia: tuple


def read_param_file(path: Path) -> list[LinkInertial]:
    """Read a parameter-set JSON (``{"links": [{name, mass, com, inertia}, ...]}``).

    An entry may carry ``"absorbed_into": "<link>"`` with mass 0: identified sets
    give all links fixed to one joint (e.g. Panda link 7 + hand + fingers) to one.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError as err:
        raise RobotDescriptionError(f"parameter file not found: {path}") from err
    except json.JSONDecodeError as err:
        raise RobotDescriptionError(f"parameter file {path} is not valid JSON: {err}") from err
    links = doc.get("links") if isinstance(doc, dict) else None
    if not isinstance(links, list) or not links:
        raise RobotDescriptionError(f"parameter file {path} has no 'links' list")
    out = []
    for i, ln in enumerate(links):
        try:
            com = tuple(None if c is None else float(c) for c in ln["com"])
            inertia = tuple(float(x) for x in ln["inertia"])
            item = LinkInertial(str(ln["name"]), float(ln["mass"]), com, inertia)
        except (KeyError, TypeError, ValueError) as err:
            raise RobotDescriptionError(f"parameter file {path}, link #{i}: needs name, mass, com[3], inertia[6] ({err})") from err
        if len(com) != 3 or len(inertia) != 6:
            raise RobotDescriptionError(f"parameter file {path}, link {item.name}: com needs 3 values and inertia 6")
        # mass 0 is allowed for a link whose inertia an identified set gave to another
        # link of the same rigid body (``"absorbed_into": "<that link>"``).
        absorbed = item.mass == 0 and bool(ln.get("absorbed_into"))
        if not ((item.mass > 0 and math.isfinite(item.mass)) or absorbed):
            raise RobotDescriptionError(f"parameter file {path}, link {item.name}: mass must be positive, got {item.mass}")
        # A negative inertia is refused (it was once accepted). A published set may break the triangle inequality
        # and say so on the link ("triangle_inequality": why it is kept), to be used as published.
        bad = inertial_problems(item.mass, item.inertia, triangle=not ln.get("triangle_inequality"))
        if bad:
            raise RobotDescriptionError(f"parameter file {path}, link {item.name}: not a rigid body: {'; '.join(bad)}")
        out.append(item)
    return out


@dataclass(frozen=True)
class GazFriction:
    """Gaz et al. 2019 sigmoid joint friction, per joint (arrays of length nv).

    tau_f(qd) = phi1 / (1 + exp(-phi2 (qd + phi3))) - phi1 / (1 + exp(-phi2 phi3))
    phi1 [Nm], phi2 [s/rad], phi3 [rad/s]. Zero at rest, saturates to about +-phi1.
    The torque is the one the friction *consumes*: tau_motor = tau_link + tau_f.
    """

    phi1: np.ndarray
    phi2: np.ndarray
    phi3: np.ndarray

    def __call__(self, qd: np.ndarray) -> np.ndarray:
        """Friction torque [Nm] at joint velocity qd [rad/s], any leading shape."""
        qd = np.asarray(qd, dtype=float)
        return self.phi1 * (_sigmoid(self.phi2 * (qd + self.phi3)) - _sigmoid(self.phi2 * self.phi3))

    @classmethod
    def from_json(cls, path: Path) -> "GazFriction":
        doc = json.loads(Path(path).read_text())
        try:
            joints = doc["friction"]["joints"]
            arr = {k: np.array([float(j[k]) for j in joints]) for k in ("phi1", "phi2", "phi3")}
        except (KeyError, TypeError) as err:
            raise RobotDescriptionError(f"{path} has no friction.joints[phi1, phi2, phi3] table") from err
        return cls(**arr)

    def to_dict(self) -> dict:
        return {k: getattr(self, k).tolist() for k in ("phi1", "phi2", "phi3")}


def _sigmoid(x):
    return 0.5 * (1.0 + np.tanh(0.5 * x))  # overflow-free logistic
