"""Identified models: fit, predict, save as a parameter file, load back as a Robot.

    model = identify(dataset, "consistent", load_robot("panda"))
    tau_hat = model.predict_torque(q, qd, qdd)          # [Nm], friction included
    model.save("panda_identified.json")                   # load_robot(..., params=that file)
    robot = model.to_robot()                              # every analytic baseline on it
    tau_f = friction_from_file("panda_identified.json")   # qd -> friction torque [Nm]

The file is the parameter-set JSON that :func:`hybrid_dyn.description.read_param_file`
reads (``{"links": [{name, mass, com, inertia}]}``) plus a ``friction`` section and
the fit statistics. Pinocchio merges every link fixed to a joint into one body
(for the Panda, joint 7 carries link 7, the flange, the hand, both fingers and any
payload), and only that sum is identifiable; the file therefore gives the whole
body to the joint's own link and lists the other links with mass 0 and
``"absorbed_into"`` naming it. Load the file *without* a payload: it is inside.
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..analytic.robot import InputError, Robot, as_batch, load_robot
from ..description import GazFriction, RobotDescriptionError
from ..errors import UsageError
from ..outputs import unique_temp
from . import least_squares as est
from .identification_methods import IDENTIFICATION_METHODS
from .extra_terms import SPRING_TERMS, spring_basis, spring_joints, spring_regressor
from .parameters import N_BODY_PARAMS, check_consistency, to_urdf_form
from .plausibility import fit_warnings
from .regressor import (DEFAULT_COULOMB_EPS, BaseParameters, base_parameters, friction_regressor,
                        inertial_regressor, nominal_body_parameters)

FILE_FORMAT = "hybrid_dyn.identified_params"


# ---------------------------------------------------------------------- friction
@dataclass(frozen=True)
class LinearFriction:
    """tau_f = fv qd + fc tanh(qd / eps) + fo per joint: fv [Nm s/rad], fc, fo [Nm], eps [rad/s]."""

    fv: np.ndarray
    fc: np.ndarray
    fo: np.ndarray
    eps: float = DEFAULT_COULOMB_EPS

    def __call__(self, qd: np.ndarray) -> np.ndarray:
        qd = np.asarray(qd, dtype=float)
        return self.fv * qd + self.fc * np.tanh(qd / self.eps) + self.fo

    def to_dict(self, joint_names) -> dict:
        return {"model": "linear", "law": "tau_f = fv*qd + fc*tanh(qd/eps) + fo", "eps": self.eps,
                "joints": [{"joint": n, "fv": float(a), "fc": float(b), "fo": float(c)}
                           for n, a, b, c in zip(joint_names, self.fv, self.fc, self.fo)]}


def _gaz_to_dict(f: GazFriction, joint_names) -> dict:
    return {"model": "gaz-sigmoid",
            "law": "tau_f = phi1/(1+exp(-phi2*(qd+phi3))) - phi1/(1+exp(-phi2*phi3))",
            "joints": [{"joint": n, "phi1": float(a), "phi2": float(b), "phi3": float(c)}
                       for n, a, b, c in zip(joint_names, f.phi1, f.phi2, f.phi3)]}


def friction_from_dict(doc: dict, where: str = "friction section"):
    """The friction callable (qd [rad/s] -> tau_f [Nm]) of a ``friction`` section."""
    try:
        joints = doc["joints"]
        if doc.get("model", "gaz-sigmoid") == "linear":
            return LinearFriction(*(np.array([float(j[k]) for j in joints]) for k in ("fv", "fc", "fo")),
                                  eps=float(doc.get("eps", DEFAULT_COULOMB_EPS)))
        return GazFriction(*(np.array([float(j[k]) for j in joints]) for k in ("phi1", "phi2", "phi3")))
    except (KeyError, TypeError, ValueError) as err:
        raise RobotDescriptionError(f"{where}: needs joints with fv, fc, fo (linear) or phi1, phi2, phi3 ({err})") from err


def friction_from_file(path) -> LinearFriction | GazFriction:
    """The friction law of an identified parameter file (or of the Gaz parameter file)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise RobotDescriptionError(f"cannot read parameter file {path}: {err}") from err
    if not isinstance(doc, dict) or "friction" not in doc:
        raise RobotDescriptionError(f"{path} has no friction section")
    return friction_from_dict(doc["friction"], str(path))


def read_identified_file(params) -> tuple[dict, str] | None:
    """(document, sha256 of its bytes) of an identified parameter file, or None when
    ``params`` is not one: None, a set name (``"gaz2019"``), or a JSON file of another
    kind (a nominal parameter set, with or without a friction section).

    Only a file :meth:`IdentifiedModel.save` wrote is a whole identified model (its
    inertials and the friction fitted with them); the residual priors take its
    friction (:class:`hybrid_dyn.learn.priors.AnalyticPrior`) and key their caches on
    the digest, so a file rewritten in place never serves a stale prior.
    """
    if params is None or Path(params).suffix != ".json" or not Path(params).is_file():
        return None
    path = Path(params)
    try:
        raw = path.read_bytes()
        doc = json.loads(raw)
    except (OSError, ValueError) as err:
        raise RobotDescriptionError(f"cannot read parameter file {path}: {err}") from err
    if not isinstance(doc, dict) or doc.get("format") != FILE_FORMAT:
        return None
    if not isinstance(doc.get("friction"), dict):
        raise RobotDescriptionError(f"{path}: an identified parameter file needs its friction section")
    return doc, hashlib.sha256(raw).hexdigest()


# -------------------------------------------------------------------------- data
@dataclass
class IdentificationData:
    """Stacked samples for identification: q, qd, qdd (N, nv) and motor torques tau (N, nv) [Nm]."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray

    @classmethod
    def from_arrays(cls, q, qd, qdd, tau, nv: int) -> "IdentificationData":
        arrs = [as_batch(x, n, nv)[0] for x, n in zip((q, qd, qdd, tau), ("q", "qd", "qdd", "tau"))]
        if len({len(a) for a in arrs}) != 1:
            raise InputError(f"q, qd, qdd, tau have different lengths: {[len(a) for a in arrs]}")
        return cls(*arrs)

    @classmethod
    def from_dataset(cls, dataset, nv: int, splits=("train", "val"), target: str = "tau_m",
                     acceleration: str = "measured") -> "IdentificationData":
        """Concatenate the instances of ``splits`` (the test split stays held out).

        acceleration: ``measured`` uses the dataset's qdd; ``zero-phase`` re-estimates
        it from qd offline without delay (:func:`.experiment.zero_phase_acceleration`).
        """
        if acceleration not in ("measured", "zero-phase"):
            raise UsageError(f"acceleration must be 'measured' or 'zero-phase', got {acceleration!r}")
        insts = [i for s in splits for i in dataset.split(s)]
        if not insts:
            raise InputError(f"the dataset has no instances in splits {splits}")
        cat = {k: np.concatenate([np.asarray(i[k]) for i in insts]) for k in ("q", "qd", target)}
        if acceleration == "measured":
            cat["qdd"] = np.concatenate([np.asarray(i["qdd"]) for i in insts])
        else:
            from .experiment import zero_phase_acceleration

            cat["qdd"] = np.concatenate([zero_phase_acceleration(i["qd"], _sample_period(i)) for i in insts])
        return cls.from_arrays(cat["q"], cat["qd"], cat["qdd"], cat[target], nv)

    def __len__(self) -> int:
        return len(self.q)


def _sample_period(inst) -> float:
    t = np.asarray(inst["t"], float)
    dt = np.diff(t)
    if len(dt) == 0 or not np.allclose(dt, dt[0], rtol=1e-6):
        raise InputError(f"instance {inst.name}: t is not uniformly sampled, cannot differentiate qd")
    return float(dt[0])


# ------------------------------------------------------------------------- model
@dataclass
class IdentifiedModel:
    """Identified inertial parameters of every body and a joint friction law.

    body_params: (nv, 10) dynamic parameters about each joint frame (Pinocchio order);
    friction: LinearFriction or GazFriction; fit: statistics of the fit (rmse_per_joint [Nm],
    condition_number of the base regressor, n_samples, ...).
    """

    robot: Robot
    method: str
    body_params: np.ndarray
    friction: LinearFriction | GazFriction
    fit: dict = field(default_factory=dict)
    # The declared springs by joint name (``extra_terms``): [k_lin, k_sin, k_cos],
    # tau_j += k_lin q_j + k_sin sin(q_j) + k_cos cos(q_j) [Nm].
    springs: dict = field(default_factory=dict)

    # ------------------------------------------------------------- predictions
    def rigid_body_torque(self, q, qd, qdd) -> np.ndarray:
        """Y(q, qd, qdd) pi: the rigid-body torques [Nm] (N, nv) of the identified bodies."""
        Y = inertial_regressor(self.robot, q, qd, qdd)
        return Y @ self.body_params.reshape(-1)

    def predict_torque(self, q, qd, qdd) -> np.ndarray:
        """Motor torques [Nm] (N, nv) = rigid body + friction, the quantity identified."""
        tau = self.rigid_body_torque(q, qd, qdd)
        qd_b, single = as_batch(qd, "qd", self.robot.nv)
        f = self.friction(qd_b)
        return tau + (f[0] if single else f) + self.spring_torque(q)

    def spring_torque(self, q) -> np.ndarray | float:
        """The declared springs' torques [Nm] ((nv,) or (N, nv)); 0.0 where the robot declares none."""
        return spring_torque(self.springs, self.robot.joint_names, q)

    def consistency(self) -> list:
        """Per-body :class:`~.parameters.ConsistencyReport` (COM box check included)."""
        boxes = est.com_boxes(self.robot, self.fit.get("com_margin", est.ConsistentConfig().com_margin))
        return [check_consistency(p, box) for p, box in zip(self.body_params, boxes)]

    @property
    def physically_consistent(self) -> bool:
        return all(r.valid for r in self.consistency())

    def implausible_bodies(self) -> list[str]:
        """One line per body outside the robot's plausibility bounds (mass, centre of mass, inertia:
        ``plausibility.PlausibilityBounds``), computed from the parameters (a file written before the check
        is checked too); empty: every body within them."""
        from .plausibility import implausible_bodies

        return implausible_bodies(self.robot, self.body_params)

    # ---------------------------------------------------------------- file I/O
    def to_dict(self) -> dict:
        links = _links_section(self.robot, self.body_params)
        fr = self.friction.to_dict(self.robot.joint_names) if isinstance(self.friction, LinearFriction) \
            else _gaz_to_dict(self.friction, self.robot.joint_names)
        return {
            "format": FILE_FORMAT, "version": 1, "robot": self.robot.name, "method": self.method,
            "conventions": {
                "links": "URDF <inertial>: mass [kg], com [m] in the link frame, inertia about the COM "
                         "[xx, xy, xz, yy, yz, zz] kg m^2; links with 'absorbed_into' are part of that link's body",
                "body_parameters": "per joint [m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] about the joint frame "
                                   "(Pinocchio order), the values predictions use",
            },
            "links": links,
            "body_parameters": {n: [float(x) for x in p] for n, p in zip(self.robot.joint_names, self.body_params)},
            "friction": fr,
            **({"springs": {"law": "tau_j = k_lin*q_j + k_sin*sin(q_j) + k_cos*cos(q_j) [Nm]",
                            "terms": list(SPRING_TERMS), "coefficients": dict(self.springs)}}
               if self.springs else {}),
            "fit": _jsonable(self.fit),
        }

    def save(self, path) -> Path:
        """Write the parameter file atomically (a per-run temporary, then rename: two runs
        writing the same file never mix their bytes)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = unique_temp(path)
        try:
            tmp.write_text(json.dumps(self.to_dict(), indent=1))
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
        return path

    @classmethod
    def load(cls, path, robot: Robot | None = None) -> "IdentifiedModel":
        """Read a file written by :meth:`save`; ``robot`` (kinematics only) defaults to the named nominal one."""
        path = Path(path)
        try:
            doc = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as err:
            raise RobotDescriptionError(f"cannot read identified parameter file {path}: {err}") from err
        if not isinstance(doc, dict) or doc.get("format") != FILE_FORMAT:
            raise RobotDescriptionError(f"{path} is not an identified parameter file (format {FILE_FORMAT!r})")
        robot = robot or load_robot(doc["robot"])
        if robot.name != doc["robot"]:
            raise RobotDescriptionError(f"{path} was identified for robot {doc['robot']!r}, not {robot.name!r}")
        bp = doc["body_parameters"]
        missing = [n for n in robot.joint_names if n not in bp]
        if missing:
            raise RobotDescriptionError(f"{path}: body_parameters lacks joints {missing}")
        params = np.array([[float(x) for x in bp[n]] for n in robot.joint_names])
        if params.shape != (robot.nv, N_BODY_PARAMS) or not np.isfinite(params).all():
            raise RobotDescriptionError(f"{path}: body_parameters must hold {N_BODY_PARAMS} finite numbers per joint")
        return cls(robot, doc["method"], params, friction_from_dict(doc["friction"], str(path)), doc.get("fit", {}),
                   springs=springs_from_dict(doc, robot.joint_names, str(path)))

    def to_robot(self, **kwargs) -> Robot:
        """A :class:`Robot` on the identified parameters (kwargs go to load_robot, e.g. sensor_mount)."""
        bad = [n for n, r in zip(self.robot.joint_names, self.consistency()) if r.mass <= 0]
        if bad:
            raise RobotDescriptionError(
                f"{self.method} parameters give non-positive mass to the bodies of {bad}: no URDF can hold them "
                f"(use the 'consistent' or 'sigmoid-friction' method)")
        # The variant's tool too (panda[tool=none]: without it the hand would come back at its
        # nominal mass); not its payload, which the joint-7 body already holds.
        kwargs.setdefault("tool", self.robot.spec.tool)
        with tempfile.TemporaryDirectory() as tmp:
            path = self.save(Path(tmp) / "identified.json")
            return load_robot(self.robot.spec.source or self.robot.name, params=path, **kwargs)


def spring_torque(springs: dict, joint_names, q) -> np.ndarray | float:
    """The declared springs' torques [Nm] ((nv,) or (N, nv)) at q [rad]; 0.0 when ``springs`` is empty.

    springs: joint name -> [k_lin, k_sin, k_cos] (``extra_terms``)."""
    if not springs:
        return 0.0
    q = np.asarray(q, float)
    out = np.zeros_like(q)
    for name, coef in springs.items():
        j = list(joint_names).index(name)
        out[..., j] = spring_basis(q[..., j]) @ np.asarray(coef, float)
    return out


def springs_from_dict(doc: dict, joint_names, where: str) -> dict:
    """The ``springs`` section of an identified file (name -> [k_lin, k_sin, k_cos]); {} when there is none."""
    section = doc.get("springs")
    if not section:
        return {}
    coefs = section.get("coefficients") if isinstance(section, dict) else None
    ok = isinstance(coefs, dict) and all(
        n in joint_names and isinstance(c, list) and len(c) == len(SPRING_TERMS)
        and all(isinstance(v, (int, float)) and np.isfinite(v) for v in c) for n, c in coefs.items())
    if not ok:
        raise RobotDescriptionError(f"{where}: the springs section must map the robot's joints to "
                                    f"{len(SPRING_TERMS)} finite coefficients {list(SPRING_TERMS)}, got {section!r}")
    return {n: [float(v) for v in c] for n, c in coefs.items()}


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    return x


def _urdf_masses(urdf_xml: str) -> dict:
    root = ET.fromstring(urdf_xml)
    out = {}
    for ln in root.findall("link"):
        m = ln.find("inertial/mass")
        out[ln.get("name")] = float(m.get("value")) if m is not None else 0.0
    return out


def _links_section(robot: Robot, body_params: np.ndarray) -> list[dict]:
    """URDF link entries: joint j's body on its child link, the other links fixed to it at mass 0."""
    model = robot.model
    masses = _urdf_masses(robot.urdf_xml)
    links = []
    for j in range(1, model.njoints):
        bodies = [f for f in model.frames if f.parentJoint == j and f.type == pin.FrameType.BODY]
        # The joint's own link: the body frame right after the joint frame.
        own = next((f for f in bodies if model.frames[f.parentFrame].type == pin.FrameType.JOINT
                    and model.frames[f.parentFrame].name == model.names[j]), None)
        if own is None:
            raise RobotDescriptionError(f"joint {model.names[j]!r} has no child link frame")
        inertia = own.placement.actInv(pin.Inertia.FromDynamicParameters(body_params[j - 1]))
        m, c, icom = to_urdf_form(inertia.toDynamicParameters())
        links.append({"name": own.name, "mass": m, "com": c.tolist(), "inertia": icom.tolist()})
        for f in bodies:
            # hd_payload is generated by load_robot(payload=...), not part of the robot's URDF
            if f.name != own.name and f.name != "hd_payload" and masses.get(f.name, 0.0) != 0.0:
                links.append({"name": f.name, "mass": 0.0, "com": [0.0, 0.0, 0.0], "inertia": [0.0] * 6,
                              "absorbed_into": own.name})
    return links


# ---------------------------------------------------------------------- identify
def _joint_rmse(tau, tau_hat) -> np.ndarray:
    return np.sqrt(np.mean((tau - tau_hat) ** 2, axis=0))


def _fit_by_method(method, robot, columns, data, sigma, pi_nom, pi_lin, phi_lin, k_lin, beta, base, eps, config, fit):
    """The method's own fit from the linear one: (pi (10 nv,), friction law, spring stiffnesses)."""
    Y, F, S, springs = columns
    nv = robot.nv
    k = k_lin
    if method in ("ols", "wls"):
        pi, friction = pi_lin, LinearFriction(phi_lin[:, 0], phi_lin[:, 1], phi_lin[:, 2], eps)
        fit["base_parameters"] = {"names": base.base_names(), "values": beta.tolist()}
    elif method == "consistent":
        # The springs' columns ride with the friction's: linear, unbounded, fitted jointly.
        pi, phi, stats = est.fit_consistent(robot, Y, np.concatenate([F, S], axis=-1), data.tau, sigma, pi_nom,
                                            np.concatenate([phi_lin.reshape(-1), k_lin]), config)
        phi, k = phi[:3 * nv].reshape(nv, 3), phi[3 * nv:]
        friction = LinearFriction(phi[:, 0], phi[:, 1], phi[:, 2], eps)
        fit.update(ipopt_status=stats["return_status"], iterations=stats["iter_count"], com_margin=config.com_margin,
                   regularization=config.regularization)
    else:
        # Start the sigmoid from the linear fit: it spans 2*phi1 between its plateaus.
        phi0 = np.stack([np.clip(2 * np.abs(phi_lin[:, 1]), 0.05, None), np.full(nv, 10.0), np.zeros(nv)], 1)
        # The sigmoid's objective has no linear block: the springs keep the consistent fit's law, taken
        # out of the target first (a two-stage fit, said in the fit record). Not the linear fit's: its
        # spring harmonics trade with unphysical bodies (Baxter: -78 kg on e0) and mean nothing without them.
        if len(springs):
            k = _fit_by_method("consistent", robot, columns, data, sigma, pi_nom, pi_lin, phi_lin, k_lin, beta,
                               base, eps, config, {})[2]
            fit["springs_fit"] = "the consistent fit's spring law, held fixed in the sigmoid fit"
        tau_nospring = data.tau - (S @ k if len(springs) else 0.0)
        pi, phi, stats = est.fit_sigmoid_friction(robot, Y, data.qd, tau_nospring, sigma, pi_nom, phi0, config)
        friction = GazFriction(phi[:, 0], phi[:, 1], phi[:, 2])
        fit.update(ipopt_status=stats["return_status"], iterations=stats["iter_count"], com_margin=config.com_margin,
                   regularization=config.regularization)
    return pi, friction, k


def identify(data, method: str = "consistent", robot: Robot | None = None, *, splits=("train", "val"),
             target: str = "tau_m", acceleration: str = "measured", eps: float = DEFAULT_COULOMB_EPS,
             base: BaseParameters | None = None,
             config: est.ConsistentConfig = est.ConsistentConfig()) -> IdentifiedModel:
    """Identify ``robot``'s inertial and friction parameters from motor torques.

    data: a :class:`~hybrid_dyn.data.Dataset` (its ``splits`` are used, the test split
      stays held out), an :class:`IdentificationData`, or a tuple (q, qd, qdd, tau).
    method: a name of ``identification_methods.IDENTIFICATION_METHODS`` (the fits: :mod:`.least_squares`).
    acceleration: for a dataset, ``measured`` (its qdd) or ``zero-phase`` (re-estimated offline).
    robot: the nominal model: its kinematics define the regressor and its inertials
      are the prior that ``consistent`` regularizes towards and the fill-in for
      directions ``ols``/``wls`` cannot see. Default: the dataset's robot, nominal.
    """
    IDENTIFICATION_METHODS.lookup(method)  # an unknown one is refused, naming the known ones
    if robot is None:
        name = getattr(data, "meta", {}).get("robot") if hasattr(data, "meta") else None
        if name is None:
            raise InputError("pass robot= (the data do not say which robot they come from)")
        robot = load_robot(name)
    if hasattr(data, "split"):
        if data.meta.get("robot") not in (None, robot.name):
            raise InputError(f"the dataset is of robot {data.meta.get('robot')!r}, the model is {robot.name!r}")
        data = IdentificationData.from_dataset(data, robot.nv, splits, target, acceleration)
    elif isinstance(data, (tuple, list)):
        data = IdentificationData.from_arrays(*data, nv=robot.nv)
    nv = robot.nv
    base = base or base_parameters(robot, friction=True, eps=eps)
    Y = inertial_regressor(robot, data.q, data.qd, data.qdd)
    F = friction_regressor(data.qd, eps)
    W = np.concatenate([Y, F], axis=-1)
    # The description's declared springs: three columns each, identified with everything else.
    springs = spring_joints(robot.spec, robot.joint_names)
    S = spring_regressor(springs, data.q, nv)
    Wb = np.concatenate([base.reduce(W), S], axis=-1)
    n_cols = Wb.shape[-1]
    if len(data) * nv < 2 * n_cols:
        raise est.IdentificationError(
            f"{len(data)} samples give {len(data) * nv} equations for {n_cols} base parameters; record more")
    cond = float(np.linalg.cond(Wb.reshape(-1, n_cols)))
    pi_nom = nominal_body_parameters(robot)

    beta, sigma = est.fit_wls(Wb, data.tau) if method != "ols" else (est.fit_ols(Wb, data.tau), None)
    if sigma is None:
        sigma = est.joint_residual_std(Wb, data.tau, beta)
    beta, k_lin = beta[:base.n_base], beta[base.n_base:]
    # Full parameters that reproduce beta exactly, closest to the nominal ones in the scaled metric.
    x_nom = np.concatenate([pi_nom, np.zeros(3 * nv)])
    scale = np.concatenate([np.tile(est.PARAM_SCALE, nv), np.ones(3 * nv)])
    KS = base.K * scale
    x = x_nom + scale * (np.linalg.pinv(KS) @ (beta - base.K @ x_nom))
    pi_lin, phi_lin = x[: N_BODY_PARAMS * nv], x[N_BODY_PARAMS * nv:].reshape(nv, 3)
    fit = {"n_samples": len(data), "condition_number": cond, "n_base": base.n_base, "coulomb_eps": eps,
           "residual_std_ols": sigma.tolist()}

    pi, friction, k = _fit_by_method(method, robot, (Y, F, S, springs), data, sigma, pi_nom, pi_lin, phi_lin, k_lin,
                                     beta, base, eps, config, fit)
    model = IdentifiedModel(robot, method, pi.reshape(nv, N_BODY_PARAMS), friction, fit,
                            springs={robot.joint_names[j]: [float(v) for v in k[3 * i:3 * i + 3]]
                                     for i, j in enumerate(springs)})
    model.fit["rmse_per_joint"] = _joint_rmse(data.tau, model.predict_torque(data.q, data.qd, data.qdd)).tolist()
    model.fit["physically_consistent"] = model.physically_consistent
    # What the data could not determine, and bodies this robot cannot have: said, not silent.
    model.fit["range_of_motion_deg"] = np.degrees(np.ptp(data.q, axis=0)).tolist()
    model.fit["warnings"] = fit_warnings(data.q, cond, robot.joint_names)
    model.fit["implausible"] = model.implausible_bodies()
    return model
