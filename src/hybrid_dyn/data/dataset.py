"""The toolkit's dataset format: a directory of HDF5 instances and a manifest.

Layout::

    DIR/manifest.json          config, seed, versions, fields, instances, splits
    DIR/instances/<name>.h5    one file per instance (a run of 5-50 trajectories)

Each instance file holds one dataset per field at its root (``t``, ``q``, ``qd``,
``qdd``, ``tau_m``, ``tau_J``, ``base_wrench``, ``tip_force``; shape (T, k),
``t`` shape (T,)) and, for simulated data, the noise-free copies under ``truth/``.

Why HDF5: it is a standard, self-describing binary format that opens from any
language without this toolkit (h5py, MATLAB ``h5read``, HDFView), stores float64
arrays exactly, compresses losslessly, and writes byte-identical files when
timestamps are off, which makes checksums and the determinism guarantee of the
generator meaningful. Nothing in it can execute code on load (unlike pickle).

Units (SI): t [s]; q [rad]; qd [rad/s]; qdd [rad/s^2]; tau_m, tau_J [Nm];
base_wrench [N, N, N, Nm, Nm, Nm]; tip_force [N].
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

import h5py
import numpy as np

from ..errors import HybridDynError, UsageError
from ..outputs import unique_temp


def is_url(location) -> bool:
    """Whether a dataset location is an fsspec URL (``s3://...``) rather than a local path (``data/store.py``
    writes to either; it imports this module, never the reverse)."""
    return isinstance(location, str) and "://" in location


FORMAT = "hybrid_dyn.dataset"
FORMAT_VERSION = 1
SPLITS = ("train", "val", "test")

FIELD_UNITS = {
    "t": "s",
    "q": "rad",
    "qd": "rad/s",
    "qdd": "rad/s^2",
    "tau_m": "Nm (commanded motor torque, friction included)",
    "tau_J": "Nm (link-side joint torque)",
    "base_wrench": "N, Nm (ground reaction on the robot in the base-sensor frame, [fx fy fz mx my mz])",
    "tip_force": "N (force of the environment on the robot at the tool point, base frame)",
}


class DatasetError(HybridDynError, ValueError):
    """A dataset directory, manifest or instance file is missing, corrupt or partial."""


def sha256_file(path: Path) -> str:
    """A file's sha256; of a folder (a ROS 2 bag), that of its files' names and digests in name order."""
    if Path(path).is_dir():
        h = hashlib.sha256()
        for p in sorted(q for q in Path(path).rglob("*") if q.is_file()):
            h.update(f"{p.relative_to(path).as_posix()}\0{sha256_file(p)}\n".encode())
        return h.hexdigest()
    with open(path, "rb") as f:
        return sha256_stream(f)


def sha256_stream(f) -> str:
    """The sha256 of an open binary file (local or fsspec), read in 1 MiB chunks."""
    h = hashlib.sha256()
    for chunk in iter(lambda: f.read(1 << 20), b""):
        h.update(chunk)
    return h.hexdigest()


def write_instance(path: Path, fields: dict, truth: dict | None = None, attrs: dict | None = None) -> str:
    """Write one instance atomically (temp file, then rename); returns its sha256.

    Byte-identical output for identical input: HDF5 timestamps are off. The
    temporary's name is unique to this call and the checksum is taken from it
    before the rename, so a concurrent writer of the same path can never make
    this call vouch for bytes it did not write.
    """
    def fill(f):
        _write_group(f, fields)
        if truth:
            _write_group(f.create_group("truth", track_order=False), truth)

    return _write_atomic(path, attrs, fill)


def write_instance_blocks(path: Path, n: int, widths: dict, block, attrs: dict | None = None,
                          rows: int = 65_536) -> str:
    """Write one instance of ``n`` samples a block of rows at a time (a long log that never sits in memory
    whole); returns its sha256. ``widths``: field -> columns (None for a (T,) field such as ``t``);
    ``block(field, a, b)``: rows a..b-1 of the field. Datasets, chunks, filters and their order are
    :func:`write_instance`'s, and each block is whole chunks, so a reader gets the same arrays."""
    def fill(f):
        for name in sorted(widths):
            shape = (n,) if widths[name] is None else (n, widths[name])
            dset = f.create_dataset(name, shape=shape, dtype=np.float64, track_times=False, compression="gzip",
                                    compression_opts=4, shuffle=True, chunks=True if n * shape[-1] > 0 else None)
            step = max(rows // dset.chunks[0], 1) * dset.chunks[0] if dset.chunks else max(n, 1)
            for a in range(0, n, step):
                dset[a:min(a + step, n)] = block(name, a, min(a + step, n))

    return _write_atomic(path, attrs, fill)


def _write_atomic(path, attrs: dict | None, fill) -> str:
    """An instance file written by ``fill(h5 file)`` under a per-call temporary, its attrs first, then renamed
    into place; returns the sha256 of the bytes this call wrote (taken before the rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = unique_temp(path)
    with h5py.File(tmp, "w", libver=("earliest", "v110"), track_order=False) as f:
        for k, v in (attrs or {}).items():
            f.attrs[k] = v
        fill(f)
    sha = sha256_file(tmp)
    os.replace(tmp, path)
    return sha


def _write_group(group, fields: dict) -> None:
    lengths = {k: len(v) for k, v in fields.items()}
    if len(set(lengths.values())) > 1:
        raise DatasetError(f"fields have different lengths: {lengths}")
    for name in sorted(fields):
        arr = np.ascontiguousarray(fields[name], dtype=np.float64)
        group.create_dataset(name, data=arr, track_times=False, compression="gzip", compression_opts=4,
                             shuffle=True, chunks=True if arr.size > 0 else None)


class Instance:
    """One recorded run. Fields are numpy arrays, loaded from disk on first use.

    ``inst.q`` or ``inst["q"]``: (T, nv); ``inst.truth["q"]``: the noise-free copy.
    ``expected_attrs``: file attributes the manifest vouches for (``scenario``,
    ``config_hash``); a file that states another value is refused on opening.
    """

    def __init__(self, name: str, path: Path, fields: list[str], n_samples: int, expected_attrs: dict | None = None):
        self.name = name
        self.path = Path(path)
        self.fields = list(fields)
        self.n_samples = n_samples
        self.expected_attrs = dict(expected_attrs or {})
        self._data: dict | None = None
        self._truth: dict | None = None

    def _load(self) -> None:
        try:
            with h5py.File(self.path, "r") as f:
                self._check_attrs(f.attrs)
                missing = [k for k in self.fields if k not in f]
                if missing:
                    raise DatasetError(f"instance {self.name} ({self.path}) lacks fields {missing}")
                self._data = {k: f[k][()] for k in self.fields}
                self._truth = {k: f["truth"][k][()] for k in f["truth"]} if "truth" in f else {}
        except OSError as err:
            raise DatasetError(f"instance {self.name}: cannot read {self.path}: {err}") from err
        n = {k: len(v) for k, v in self._data.items()}
        if set(n.values()) != {self.n_samples}:
            raise DatasetError(f"instance {self.name}: expected {self.n_samples} samples, file has {n}")

    def _check_attrs(self, attrs) -> None:
        """The file's own scenario and config hash must be the manifest's: a file copied in from
        another dataset (its checksum re-recorded) would otherwise train or score silently."""
        for key, want in self.expected_attrs.items():
            if key in attrs and str(attrs[key]) != str(want):
                raise DatasetError(f"instance {self.name}: file {self.path} has {key} {str(attrs[key])!r}, "
                                   f"the manifest {str(want)!r}; it belongs to another dataset")

    def __getitem__(self, key: str) -> np.ndarray:
        if self._data is None:
            self._load()
        try:
            return self._data[key]
        except KeyError:
            raise KeyError(f"instance {self.name} has no field {key!r}; fields: {self.fields}") from None

    def __getattr__(self, key: str) -> np.ndarray:
        if key.startswith("_") or key in ("name", "path", "fields", "n_samples", "expected_attrs"):
            raise AttributeError(key)
        try:
            return self[key]
        except KeyError as err:
            raise AttributeError(str(err)) from None

    @property
    def truth(self) -> dict:
        if self._data is None:
            self._load()
        return self._truth

    def __len__(self) -> int:
        return self.n_samples

    def __repr__(self) -> str:
        return f"Instance({self.name!r}, n_samples={self.n_samples})"


@dataclass
class Dataset:
    """A loaded dataset: ``.meta`` (the manifest) and ``.split(name)``."""

    path: Path
    meta: dict
    instances: dict = field(default_factory=dict)  # name -> Instance

    def split(self, name: str) -> list[Instance]:
        if name not in SPLITS:
            raise UsageError(f"split must be one of {SPLITS}, got {name!r}")
        return [self.instances[n] for n in self.meta["splits"][name]]

    @property
    def fields(self) -> list[str]:
        return list(self.meta["fields"])

    @property
    def checksum(self) -> str:
        """A digest of the manifest's instance checksums: identifies the data a model saw."""
        h = hashlib.sha256()
        for inst in self.meta["instances"]:
            h.update(f"{inst['name']}:{inst['sha256']};".encode())
        return h.hexdigest()

    def windows(self, split: str, length: int, inputs: list[str], targets: list[str], extra: dict | None = None):
        """Sliding windows over one split; see :class:`WindowedSplit`."""
        from .input_windows import WindowedSplit

        return WindowedSplit(self.split(split), length, inputs, targets, extra=extra)


def read_manifest(path: Path) -> dict:
    path = Path(path)
    mpath = path / "manifest.json"
    if not path.is_dir():
        raise DatasetError(f"no dataset at {path}: not a directory")
    if not mpath.is_file():
        raise DatasetError(f"{path} has no manifest.json: not a dataset, or its generation never finished")
    try:
        meta = json.loads(mpath.read_text())
    except json.JSONDecodeError as err:
        raise DatasetError(f"{mpath} is corrupt: {err}") from err
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise DatasetError(f"{mpath} is not a {FORMAT} manifest")
    version = meta.get("format_version", 0)
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise DatasetError(f"{mpath} has format version {version!r}; this toolkit reads integers <= {FORMAT_VERSION}")
    check_manifest(meta, mpath)
    return meta


def check_manifest(meta: dict, where) -> None:
    """Refuse a manifest whose structure would fail later, or mislead, naming the key.

    Checked: the required keys and their types; every instance record has a unique
    ``name``, a ``file`` confined to the dataset folder (relative, no ``..``), a
    ``sha256`` and an integer ``n_samples``; ``splits`` maps each of ``SPLITS`` to a
    list of known instance names, and no instance is in two splits or twice in one
    (a train/test overlap would score a model on data it was trained on).
    """
    for key in ("instances", "splits", "fields"):
        if key not in meta:
            raise DatasetError(f"{where} lacks {key!r}")
    if not isinstance(meta["fields"], (dict, list)) or not all(isinstance(k, str) for k in meta["fields"]):
        raise DatasetError(f"{where}: 'fields' must map field names to units, got {meta['fields']!r:.80}")
    if not isinstance(meta["instances"], list):
        raise DatasetError(f"{where}: 'instances' must be a list of records, got {type(meta['instances']).__name__}")
    names, files = set(), set()
    for k, rec in enumerate(meta["instances"]):
        if not isinstance(rec, dict):
            raise DatasetError(f"{where}: instances[{k}] must be a record (object), got {rec!r:.80}")
        for key, kind in (("name", str), ("file", str), ("sha256", str), ("n_samples", int)):
            if key not in rec:
                raise DatasetError(f"{where}: instances[{k}] ({rec.get('name', 'unnamed')}) lacks {key!r}")
            if not isinstance(rec[key], kind) or isinstance(rec[key], bool):
                raise DatasetError(f"{where}: instances[{k}] ({rec.get('name', 'unnamed')}): {key!r} must be "
                                   f"{kind.__name__}, got {rec[key]!r:.80}")
        if rec["name"] in names:
            raise DatasetError(f"{where}: instance {rec['name']!r} is listed twice")
        _check_confined(rec["file"], f"{where}: instance {rec['name']!r}")
        if rec["file"] in files:
            raise DatasetError(f"{where}: instance {rec['name']!r} shares file {rec['file']!r} with another instance")
        names.add(rec["name"])
        files.add(rec["file"])
    splits = meta["splits"]
    if not isinstance(splits, dict):
        raise DatasetError(f"{where}: 'splits' must map {list(SPLITS)} to lists of instance names, "
                           f"got {type(splits).__name__}")
    unknown_splits = sorted(set(splits) - set(SPLITS))
    if unknown_splits:
        raise DatasetError(f"{where}: unknown splits {unknown_splits}; splits are {list(SPLITS)}")
    seen: dict[str, str] = {}
    for split in SPLITS:
        if split not in splits:
            raise DatasetError(f"{where}: 'splits' lacks {split!r} (an empty list if it has no instances)")
        members = splits[split]
        if not isinstance(members, list) or not all(isinstance(n, str) for n in members):
            raise DatasetError(f"{where}: split {split!r} must be a list of instance names, got {members!r:.80}")
        unknown = [n for n in members if n not in names]
        if unknown:
            raise DatasetError(f"{where}: split {split!r} names unknown instances {unknown[:5]}")
        for n in members:
            if n in seen:
                again = "twice" if seen[n] == split else f"in both {seen[n]!r} and {split!r}"
                raise DatasetError(f"{where}: instance {n!r} is {again}; each instance belongs to one split")
            seen[n] = split


def _check_confined(file: str, who: str) -> None:
    """An instance file is a relative path inside the dataset folder: no absolute path, no ``..``."""
    rel = PurePosixPath(file)
    # A backslash is a Windows separator ("..\\x.h5" escapes there): refused on every system.
    if not rel.parts or rel.is_absolute() or ".." in rel.parts or "\\" in file:
        raise DatasetError(f"{who}: file {file!r} must be a relative path inside the dataset folder "
                           f"(no absolute path, no '..', '/' as separator)")


def load_dataset(path, verify: bool = True) -> Dataset:
    """Open a dataset directory. With ``verify``, every instance file must exist
    and match the checksum in the manifest; a missing, partial or corrupt one is
    reported by name."""
    if is_url(path):
        raise DatasetError(f"{path} is a URL: copy it to a local directory first "
                           "(hybrid_dyn.data.store.fetch_dataset(url, local_dir))")
    path = Path(path)
    meta = read_manifest(path)
    instances = {}
    problems = []
    # What each generated file states about itself (imported files state neither).
    expected = {k: meta[k] for k in ("scenario", "config_hash") if meta.get(k) is not None}
    for rec in meta["instances"]:
        ipath = path / rec["file"]
        if not ipath.is_file():
            problems.append(f"{rec['name']}: file {rec['file']} is missing")
        elif verify and sha256_file(ipath) != rec["sha256"]:
            problems.append(f"{rec['name']}: file {rec['file']} does not match its checksum (corrupt or partial)")
        instances[rec["name"]] = Instance(rec["name"], ipath, meta["fields"], rec["n_samples"], expected)
    if problems:
        raise DatasetError(f"dataset {path}: " + "; ".join(problems))
    return Dataset(path, meta, instances)


def split_by_instance(names: list[str], seed: int, test_frac: float = 0.2, val_frac: float = 0.2) -> dict:
    """The reference study's split (PROTOCOL 3): 20 % test, then 20 % of the rest validation.

    Seeded, and independent of instance order or worker count. Every split gets
    at least one instance when there are three or more.
    """
    names = sorted(names)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x5B117]))
    order = [names[i] for i in rng.permutation(len(names))]
    n_test, n_val = split_counts(len(order), test_frac, val_frac)
    test, val, train = order[:n_test], order[n_test:n_test + n_val], order[n_test + n_val:]
    return {"train": sorted(train), "val": sorted(val), "test": sorted(test)}


def split_counts(n: int, test_frac: float = 0.2, val_frac: float = 0.2) -> tuple[int, int]:
    """(n_test, n_val) of ``n`` instances: ``test_frac`` of them, then ``val_frac`` of the rest, each at
    least one when there are three or more (none below three: all train)."""
    n_test = max(1, round(test_frac * n)) if n >= 3 else 0
    n_val = max(1, round(val_frac * (n - n_test))) if n >= 3 else 0
    return n_test, n_val


def manifest_text(meta: dict) -> str:
    """The manifest.json text of ``meta``, format keys added and required keys checked."""
    meta = dict(meta)
    meta.setdefault("format", FORMAT)
    meta.setdefault("format_version", FORMAT_VERSION)
    for key in ("instances", "splits", "fields"):
        if key not in meta:
            raise DatasetError(f"manifest lacks {key!r}")
    return json.dumps(meta, indent=1, sort_keys=True)


def write_manifest(path: Path, meta: dict) -> None:
    """Write manifest.json atomically; required keys are checked."""
    text = manifest_text(meta)
    path = Path(path)
    tmp = unique_temp(path / "manifest.json")
    tmp.write_text(text)
    os.replace(tmp, path / "manifest.json")


def package_versions(names=("hybrid-dyn", "numpy", "pin", "dartpy", "torch", "h5py", "casadi", "ruckig")) -> dict:
    import importlib.metadata as md

    out = {}
    for n in names:
        try:
            out[n] = md.version(n)
        except md.PackageNotFoundError:
            pass
    return out
