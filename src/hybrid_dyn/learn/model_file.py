"""The files of a saved model, written once for every model family: the PyTorch models
(``learn/trained_model.py``) and the Gaussian processes (``learn/gp.py``).

A model folder holds ``model.safetensors`` (every tensor; its metadata one key holding the canonical
JSON of the format, its version, the sha256 of the canonical config and the sha256 of the tensors'
names, dtypes, shapes and bytes), ``config.json`` and, outside both digests, ``timing.json`` (wall-clock
figures), so that two identical runs write byte-identical config and tensors. Each file is written
through a temporary and renamed into place, config.json last: a folder with it is complete.

A family declares once what differs (:class:`ModelFiles`: its format, the framework its tensors load
in, its temporaries' names, the words of its messages); the rest is here: writing, reading the files
back and checking their digests, reusing a finished model of the same run, and refusing a folder that
holds files no run of ours wrote. :class:`SavedModel` is the base of both families' models.
Nothing is unpickled.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import torch
from safetensors import safe_open

from ..errors import HybridDynError
from ..outputs import json_marker, refuse_foreign, refuse_foreign_files

METADATA_KEY = "hybrid_dyn"
TIMING_FORMAT = "hybrid_dyn.model-timing"


class ModelError(HybridDynError, ValueError):
    """A model directory is missing, tampered with, or does not fit the robot or data."""


# ------------------------------------------------------------------ digests
def canonical_json(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"))


def config_digest(config: dict) -> str:
    return hashlib.sha256(canonical_json(config).encode()).hexdigest()


def tensors_digest(tensors: dict) -> str:
    """sha256 over every tensor's name, dtype, shape and raw bytes, in name order.

    Stored in the safetensors metadata: a flipped bit anywhere in the weights or
    the normalization buffers changes it (the config digest does not see them).
    """
    h = hashlib.sha256()
    for name in sorted(tensors):
        t = tensors[name].detach().cpu().contiguous()
        h.update(f"{name}:{t.dtype}:{list(t.shape)};".encode())
        h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes())
    return h.hexdigest()


def read_file_metadata(meta: dict) -> dict:
    """format, config_sha256 and (from format 2 on) tensors_sha256 of a model file's metadata."""
    if METADATA_KEY in meta:
        try:
            doc = json.loads(meta[METADATA_KEY])
        except ValueError:
            return {}
        return doc if isinstance(doc, dict) else {}
    return {k: meta[k] for k in ("format", "config_sha256") if k in meta}  # format 1: two plain keys


# ------------------------------------------------------------------ timing.json
def timing_doc(digest: str, train_seconds: float, train_cpu_seconds: float | None = None) -> dict:
    """timing.json's content: wall-clock training time [s] and, when measured, its CPU time [s]."""
    doc = {"format": TIMING_FORMAT, "config_sha256": digest, "train_seconds": float(train_seconds)}
    if train_cpu_seconds is not None and np.isfinite(train_cpu_seconds):
        doc["train_cpu_seconds"] = float(train_cpu_seconds)
    return doc


def read_timing(path: Path, digest: str, key: str = "train_seconds") -> float | None:
    """``key`` (train_seconds, train_cpu_seconds) from timing.json when it belongs to this config (None
    otherwise: a model trained before the figure was recorded lacks train_cpu_seconds)."""
    try:
        doc = json.loads(path.read_text())
        if doc.get("format") == TIMING_FORMAT and doc.get("config_sha256") == digest:
            return float(doc[key])
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        pass  # a lost or foreign timing file only loses a figure no result depends on
    return None


def recorded_train_cpu(model) -> float:
    """The CPU time [s] a saved model's training took (its timing.json), NaN when not recorded
    (a model without a folder, or trained before CPU time was recorded)."""
    path = getattr(model, "path", None)
    if path is None:
        return float("nan")
    cpu = read_timing(Path(path) / "timing.json", config_digest(model.config), "train_cpu_seconds")
    return float("nan") if cpu is None else cpu


# ------------------------------------------------------------------ reading files whole
def read_model_config(model_dir: Path, what: str):
    """The parsed config.json of a finished model folder (config.json and model.safetensors both
    there), or a ModelError naming the folder; what: "model" or "GP model", for the message."""
    cpath = model_dir / "config.json"
    if not cpath.is_file() or not (model_dir / "model.safetensors").is_file():
        raise ModelError(f"{model_dir} is not a finished {what} (needs config.json and model.safetensors)")
    try:
        return json.loads(cpath.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ModelError(f"{cpath} is corrupt: {err}") from err


def safetensors_metadata(path: Path, framework: str = "pt") -> dict | None:
    """The metadata of a safetensors file, None when it cannot be read (unreadable is simply not ours)."""
    try:
        with safe_open(str(path), framework=framework) as f:
            return f.metadata() or {}
    except Exception:  # safetensors raises its own error types
        return None


def json_doc(path: Path) -> dict | None:
    """The JSON object in ``path``, None for a missing or unreadable file or one that holds no object."""
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


# ------------------------------------------------------------------ one family's files
def partial(path: Path) -> Path:
    """``<path>.partial``: the temporary of a file only one run writes (it holds the folder's lock)."""
    return path.with_name(path.name + ".partial")


@dataclass(frozen=True)
class ModelFiles:
    """The files of one model family: what differs between families, and the file work they share.

    format, version: config.json's and the metadata's ``format`` and ``format_version``.
    what: the model in messages ("model", "GP model"); its folder is "<what> folder".
    framework: the safetensors framework its tensors load in ("pt": torch, "np": numpy).
    save_tensors(tensors, path, metadata=...): safetensors' ``save_file`` of that framework.
    digest(tensors) -> str: the tensor digest (:func:`tensors_digest`, on that framework's tensors).
    temporary(path) -> path: the temporary a file is written to before its rename.
    own_temporary: the names of the temporaries a run writes into the folder.
    saved_with, redo, run_differs, choose: words of the messages (what config.json was saved with; how to
    make the model again; what another run differs in; the option that picks another folder).
    """

    format: str
    version: int
    what: str
    framework: str
    save_tensors: Callable
    digest: Callable
    temporary: Callable
    own_temporary: re.Pattern
    saved_with: str
    redo: str
    run_differs: str
    choose: str

    @property
    def folder(self) -> str:
        return f"{self.what} folder"

    def metadata(self, config: dict, tensors: dict) -> dict:
        """The safetensors metadata of a model file: one key holding canonical JSON.

        One key because safetensors writes several in hash-map order, which differs
        between processes: the file of two identical runs would differ in its header.
        """
        return {METADATA_KEY: canonical_json({"format": self.format, "format_version": self.version,
                                              "config_sha256": config_digest(config),
                                              "tensors_sha256": self.digest(tensors)})}

    def write(self, model_dir, tensors: dict, config: dict, train_seconds: float | None = None,
              train_cpu_seconds: float | None = None) -> None:
        """Write model.safetensors, timing.json (when ``train_seconds`` [s] is given; with ``train_cpu_seconds``
        [s] when known) and config.json, each through its temporary and renamed into place."""
        model_dir = Path(model_dir)
        model_dir.mkdir(parents=True, exist_ok=True)
        wpath, cpath, tpath = model_dir / "model.safetensors", model_dir / "config.json", model_dir / "timing.json"
        wtmp, ctmp = self.temporary(wpath), self.temporary(cpath)
        self.save_tensors(tensors, str(wtmp), metadata=self.metadata(config, tensors))
        ctmp.write_text(json.dumps(config, indent=1, sort_keys=True))
        # Tensors first, config last: a model folder with config.json is complete.
        os.replace(wtmp, wpath)
        if train_seconds is not None:
            ttmp = self.temporary(tpath)
            ttmp.write_text(json.dumps(timing_doc(config_digest(config), train_seconds, train_cpu_seconds), indent=1))
            os.replace(ttmp, tpath)
        os.replace(ctmp, cpath)

    # ---- reading back: each family's load calls these in the order of its checks
    def read_config(self, model_dir: Path):
        return read_model_config(model_dir, self.what)

    def read_tensors(self, model_dir: Path) -> tuple[dict, dict]:
        """(metadata, tensors) of the folder's model.safetensors; a ModelError when it cannot be read."""
        wpath = model_dir / "model.safetensors"
        try:
            with safe_open(str(wpath), framework=self.framework) as f:
                meta = read_file_metadata(f.metadata() or {})
                tensors = {k: f.get_tensor(k) for k in f.keys()}
        except Exception as err:  # safetensors raises its own error types
            raise ModelError(f"{wpath} is corrupt: {err}") from err
        return meta, tensors

    def check_config_digest(self, model_dir: Path, config: dict, meta: dict) -> None:
        """config.json is the one written with the tensors (its digest in their metadata)."""
        if meta.get("config_sha256") != config_digest(config):
            raise ModelError(f"{model_dir / 'config.json'} does not match the {self.saved_with} it was saved with "
                             f"(edited or tampered); refusing to load")

    def check_tensors_digest(self, model_dir: Path, meta: dict, tensors: dict) -> None:
        """The tensors' bytes are those saved (a flipped bit changes their digest)."""
        if meta.get("tensors_sha256") != self.digest(tensors):
            raise ModelError(f"{model_dir / 'model.safetensors'}: its tensors do not match the sha256 saved with them "
                             f"(corrupted or edited); refusing to load; {self.redo} or restore the file")

    def train_seconds(self, model_dir: Path, config: dict) -> float | None:
        """The wall-clock training time [s] timing.json records for this config (None when it does not)."""
        return read_timing(model_dir / "timing.json", config_digest(config))

    # ---- a folder before training: reuse what this run finished, refuse what no run of ours wrote
    def reuse(self, out_dir: Path, fingerprint: str, load: Callable):
        """The finished model in ``out_dir`` (``load(out_dir)``) when it is this run's (its ``fingerprint``)."""
        # A user's config.json (no toolkit format at all) is refused as theirs; another of our formats
        # gets load's own message.
        if json_marker(out_dir / "config.json", "format") is None:
            refuse_foreign(out_dir, self.folder, f"its config.json lacks the format {self.format!r}")
        model = load(out_dir)
        if model.config.get("fingerprint") != fingerprint:
            raise ModelError(f"{out_dir} holds a finished {self.what} of another run (other {self.run_differs}); "
                             f"choose another {self.choose} or delete it")
        return model

    def is_own(self, path: Path) -> bool:
        """Whether ``path`` (in a folder without config.json) is one of this family's files.

        Proof is in the content, not the name alone: our metadata or JSON keys. Temporaries
        are known by name (a temporary is partial by nature).
        """
        if not path.is_file():
            return False
        if self.own_temporary.fullmatch(path.name):
            return True
        if path.name == "model.safetensors":  # killed between writing the tensors and the config
            return read_file_metadata(safetensors_metadata(path, self.framework) or {}).get("format") == self.format
        if path.name == "timing.json":
            return (json_doc(path) or {}).get("format") == TIMING_FORMAT
        return False

    def refuse_foreign_files(self, out_dir: Path, is_own: Callable | None = None) -> None:
        """An output folder must be missing, empty, or hold only what a run writes (``is_own``, else :meth:`is_own`)."""
        refuse_foreign_files(out_dir, self.folder, is_own or self.is_own)


# ------------------------------------------------------------------ the base of every family's model
class SavedModel:
    """What a model of any family is beside its numbers: ``config`` (config.json's dict), ``path`` (its
    folder; None before it is saved) and the facts training recorded. ``FILES``: its family's files."""

    FILES: ModelFiles

    def __init__(self, config: dict, path: Path | None = None, train_seconds: float | None = None):
        self.config = config
        self.path = path
        self._train_seconds = train_seconds

    @property
    def train_seconds(self) -> float:
        """Wall-clock training time [s] (timing.json; NaN when it is not known)."""
        if self._train_seconds is not None:
            return float(self._train_seconds)
        return float(self.config.get("train_seconds", float("nan")))  # model format 1 kept it in the config

    @property
    def history(self) -> list:
        """Per-epoch train and validation losses (none for a model fitted, not trained in steps: a GP)."""
        return self.config.get("history", [])

    @property
    def val_loss(self) -> float:
        """Validation loss (standardized MSE), NaN when there was no validation split."""
        return float(self.config.get("val_loss", float("nan")))
