"""ROS bags written here with the ``rosbags`` writers (real message types, no hand-made files), from
signals whose truth the tests know.

- ``panda_signals``: a slow Panda motion at 1 kHz, its exact base wrench (``robot.base_wrench``) with a
  known tip force and base-sensor noise, the joint torques;
- ``write_bag``: /joint_states (``sensor_msgs/msg/JointState``), /ft_base and /ft_tool
  (``geometry_msgs/msg/WrenchStamped``) into a ROS 2 bag (MCAP or sqlite3) or a ROS 1 ``.bag``, with the
  knobs a test needs (joint order per message, extra joints, stamps, frames);
- ``ros_spec``: the import spec of such a bag.
"""
from pathlib import Path

import numpy as np

T0_NS = 1_764_000_000_000_000_000  # an epoch stamp [ns]: 2025-11-24, as a real bag has
PANDA_JOINTS = [f"panda_joint{j}" for j in range(1, 8)]
FINGERS = ["panda_finger_joint1", "panda_finger_joint2"]


def panda_signals(robot, n=3000, hz=1000.0, seed=0, force=None, base_noise=0.1, tau_noise=0.0):
    """A slow motion about home (exact q, qd, qdd from per-joint sines) and what the sensors read.

    ``force``: (n, 3) tip force [N] on the robot at the tool point, base frame (default none). The base
    wrench is the rigid-body reaction with that force plus white noise (``base_noise`` N on forces, a
    tenth of it in Nm on moments); the joint torques with ``tau_noise`` Nm of it. Returns a dict of arrays and ``stamps`` [ns] at ``hz``."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / hz
    amp, w = rng.uniform(0.05, 0.15, robot.nv), rng.uniform(0.5, 1.5, robot.nv)
    q = np.array(robot.spec.home) + amp * np.sin(w * t[:, None])
    qd, qdd = amp * w * np.cos(w * t[:, None]), -amp * w**2 * np.sin(w * t[:, None])
    f = np.zeros((n, 3)) if force is None else force
    jv = robot.tip_jacobian(q)[:, :3]
    tau = robot.inverse_dynamics(q, qd, qdd) - np.einsum("nij,ni->nj", jv, f)
    wrench = robot.base_wrench(q, qd, qdd, tip_force=f)
    tau = tau + rng.normal(0, 1, tau.shape) * tau_noise if tau_noise else tau  # the default draws nothing: seeds hold
    wrench = wrench + rng.normal(0, base_noise, wrench.shape) * np.r_[np.ones(3), np.full(3, 0.1)]
    stamps = T0_NS + np.round(t * 1e9).astype(np.int64)
    return {"t": t, "q": q, "qd": qd, "qdd": qdd, "tau": tau, "base_wrench": wrench, "tip_force": f,
            "stamps": stamps}


def _store(kind):
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC if kind == "ros1" else Stores.ROS2_HUMBLE)


def _header(store, kind, stamp, frame, seq):
    Header, Time = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    stamp = Time(sec=int(stamp) // 10**9, nanosec=int(stamp) % 10**9)
    return Header(seq=seq, stamp=stamp, frame_id=frame) if kind == "ros1" else Header(stamp=stamp, frame_id=frame)


def write_bag(path, sig, kind="mcap", joint_order=None, extra_joints=(), js_stamps=None, wrench_stamps=None,
              base_frame="panda_link0", tip=True, base=True, receive_ns=None, joints=PANDA_JOINTS, gripper=False,
              empty=None):
    """Write ``sig`` (``panda_signals``) as a bag at ``path`` (a folder for ROS 2, a ``.bag`` for ROS 1).

    ``joint_order(k)``: the joint order of message k (a permutation of 0..6; default the robot's);
    ``extra_joints``: names of another arm's joints in the same messages (values 9.9: never the robot's);
    ``js_stamps`` / ``wrench_stamps``: header stamps [ns] (default ``sig["stamps"]``; 0 = unset);
    ``receive_ns``: the bag's receive times [ns] (default ``sig["stamps"]``: the recorder's clock).
    ``gripper``: after each message, one naming only the gripper's fingers (franka_ros's layout: values
    9.9, never the robot's); ``empty(k)``: the fields ("velocity", "effort") message k leaves empty.
    Returns the path a spec names: the folder, the ``.mcap`` file in it, or the ``.bag``."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer as Writer2

    path, store = Path(path), _store(kind)
    ser = (lambda m, t: store.serialize_ros1(m, t)) if kind == "ros1" else (lambda m, t: store.serialize_cdr(m, t))
    n = len(sig["t"])
    js_stamps = sig["stamps"] if js_stamps is None else np.asarray(js_stamps)
    wrench_stamps = sig["stamps"] if wrench_stamps is None else np.asarray(wrench_stamps)
    if receive_ns is None:  # the recorder's clock: the true times, whatever the headers say
        receive_ns = sig["stamps"]
    JointState, WrenchStamped = store.types["sensor_msgs/msg/JointState"], store.types["geometry_msgs/msg/WrenchStamped"]
    Wrench, Vector3 = store.types["geometry_msgs/msg/Wrench"], store.types["geometry_msgs/msg/Vector3"]
    writer = Writer1(path) if kind == "ros1" else Writer2(
        path, version=9, storage_plugin=StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3)
    with writer:
        js = writer.add_connection("/joint_states", JointState.__msgtype__, typestore=store)
        ft = writer.add_connection("/ft_base", WrenchStamped.__msgtype__, typestore=store) if base else None
        tool = writer.add_connection("/ft_tool", WrenchStamped.__msgtype__, typestore=store) if tip else None
        extra = np.full(len(extra_joints), 9.9)
        for k in range(n):
            order = np.arange(len(joints)) if joint_order is None else np.asarray(joint_order(k))
            names = [joints[j] for j in order] + list(extra_joints)
            vals = lambda x: np.r_[x[k][order], extra]  # noqa: E731
            gone = empty(k) if empty is not None else ()
            msg = JointState(header=_header(store, kind, js_stamps[k], "", k), name=names, position=vals(sig["q"]),
                             velocity=np.zeros(0) if "velocity" in gone else vals(sig["qd"]),
                             effort=np.zeros(0) if "effort" in gone else vals(sig["tau"]))
            writer.write(js, int(receive_ns[k]), ser(msg, JointState.__msgtype__))
            if gripper:
                fingers = JointState(header=_header(store, kind, js_stamps[k], "", k), name=FINGERS,
                                     position=np.full(2, 9.9), velocity=np.zeros(2), effort=np.zeros(2))
                writer.write(js, int(receive_ns[k]), ser(fingers, JointState.__msgtype__))
            for conn, x, frame in ((ft, sig["base_wrench"][k], base_frame),
                                   (tool, np.r_[sig["tip_force"][k], np.zeros(3)], base_frame)):
                if conn is None:
                    continue
                wrench = Wrench(force=Vector3(x=x[0], y=x[1], z=x[2]), torque=Vector3(x=x[3], y=x[4], z=x[5]))
                msg = WrenchStamped(header=_header(store, kind, wrench_stamps[k], frame, k), wrench=wrench)
                writer.write(conn, int(receive_ns[k]), ser(msg, WrenchStamped.__msgtype__))
    return path / f"{path.name}.mcap" if kind == "mcap" else path


def ros_spec(folder, bag, name="my-bag", tip=True, base=True, extra="", blocks=0):
    """The import spec of a bag written by ``write_bag``, in ``folder/spec.toml``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    text = (f'name = "{name}"\nrobot = "panda"\n[source]\nfiles = ["{Path(bag).resolve().as_posix()}"]\n'
            '[ros]\njoint_states = "/joint_states"\n' + ('base_wrench = "/ft_base"\n' if base else "")
            + ('tip_wrench = "/ft_tool"\n' if tip else "") + extra)
    if blocks:  # one recording cut in this many time blocks, split in time order (a bench needs a test split)
        text += (f'[trajectories]\nfrom = "blocks"\nn_blocks = {blocks}\n[split]\nby = "time"\ntest_frac = 0.2\n'
                 'val_frac = 0.25\n')
    spec = folder / "spec.toml"
    spec.write_text(text)
    return spec
