"""What a model folder may hold: a finished model of this run is reused, anything training did not
write is refused, never overwritten.

Apart from the loop because it is a question about files, not about training: whether a folder
is ours is decided from its contents (our metadata, our JSON keys, our temporaries' names) before
the loop starts, and the GP (``gp.py``) answers the same question for its own files.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

from safetensors import safe_open

from ..outputs import json_marker, refuse_foreign, refuse_foreign_files
from .trained_model import MODEL_FORMAT, TIMING_FORMAT, ModelError, TrainedModel, load_model, read_file_metadata


def _reuse(out_dir: Path, fingerprint: str) -> TrainedModel:
    # A user's config.json (no toolkit format at all) is refused as theirs; another of our formats (a GP's)
    # gets load_model's own message.
    if json_marker(out_dir / "config.json", "format") is None:
        refuse_foreign(out_dir, "model folder", f"its config.json lacks the format {MODEL_FORMAT!r}")
    model = load_model(out_dir)
    if model.config.get("fingerprint") != fingerprint:
        raise ModelError(f"{out_dir} holds a finished model of another run (other preset, config or data); "
                         "choose another --out or delete it")
    return model


# What training writes into its folder (and nothing else is replaced there).
_OWN_TEMPORARY = re.compile(r"(model\.safetensors|config\.json|timing\.json|checkpoint\.safetensors|checkpoint\.json)"
                            r"\.partial")
_OWN_CACHE = re.compile(r"prior-[a-z-]+-[0-9a-f]+\.h5(\.partial)?")


def _safetensors_metadata(path: Path) -> dict | None:
    try:
        with safe_open(str(path), framework="pt") as f:
            return f.metadata() or {}
    except Exception:  # safetensors raises its own error types: unreadable is simply not ours
        return None


def _json_doc(path: Path) -> dict | None:
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


def _is_own(path: Path) -> bool:
    """Whether ``path`` (in a model folder without config.json) is something training wrote.

    Proof is in the content, not the name alone: our metadata or JSON keys. Temporaries
    and prior caches are known by name (a temporary is partial by nature).
    """
    name = path.name
    if path.is_dir():
        return name == "analytic_cache" and all(p.is_file() and _OWN_CACHE.fullmatch(p.name) for p in path.iterdir())
    if not path.is_file():
        return False
    if _OWN_TEMPORARY.fullmatch(name):
        return True
    if name == "model.safetensors":  # killed between writing the weights and the config
        return read_file_metadata(_safetensors_metadata(path) or {}).get("format") == MODEL_FORMAT
    if name == "checkpoint.safetensors":
        return "fingerprint" in (_safetensors_metadata(path) or {})
    if name == "checkpoint.json":
        doc = _json_doc(path) or {}
        return {"fingerprint", "epoch", "history"} <= set(doc)
    if name == "timing.json":
        return (_json_doc(path) or {}).get("format") == TIMING_FORMAT
    return False


def _refuse_foreign_files(out_dir: Path) -> None:
    """An output folder must be missing, empty, or hold only what training writes."""
    refuse_foreign_files(out_dir, "model folder", _is_own)
