"""What a model folder may hold: a finished model of this run is reused, anything training did not
write is refused, never overwritten.

Apart from the loop because it is a question about files, not about training: whether a folder
is ours is decided from its contents (our metadata, our JSON keys, our temporaries' names) before
the loop starts. The model's own files are judged as for every model family (``model_file.py``,
which the GP's folder uses too); what training adds is judged here: its checkpoints and the
analytic prior's cache.
"""
from __future__ import annotations

import re
from pathlib import Path

from .model_file import json_doc, safetensors_metadata
from .trained_model import MODEL_FILES, TrainedModel, load_model


def _reuse(out_dir: Path, fingerprint: str) -> TrainedModel:
    return MODEL_FILES.reuse(out_dir, fingerprint, load_model)


_OWN_CACHE = re.compile(r"prior-[a-z-]+-[0-9a-f]+\.h5(\.partial)?")


def _is_own(path: Path) -> bool:
    """Whether ``path`` (in a model folder without config.json) is something training wrote: the model's
    files (``ModelFiles.is_own``), a checkpoint (``checkpoints.py``) or the prior's cache (by name)."""
    name = path.name
    if path.is_dir():
        return name == "analytic_cache" and all(p.is_file() and _OWN_CACHE.fullmatch(p.name) for p in path.iterdir())
    if name == "checkpoint.safetensors" and path.is_file():
        return "fingerprint" in (safetensors_metadata(path) or {})
    if name == "checkpoint.json" and path.is_file():
        doc = json_doc(path) or {}
        return {"fingerprint", "epoch", "history"} <= set(doc)
    return MODEL_FILES.is_own(path)


def _refuse_foreign_files(out_dir: Path) -> None:
    """An output folder must be missing, empty, or hold only what training writes."""
    MODEL_FILES.refuse_foreign_files(out_dir, _is_own)
