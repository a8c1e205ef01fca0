"""Estimator spellings of older model files: read once, with one warning that names the upgrade.

Model format 3 writes the analytic prior by its canonical estimator name
(``analytic/method_names.py``: ``base-wrench``, ``momentum-observer``, ``rnea-bw``) in the
preset (``preset.prior``) and in the prior's description (``prior.kind``). Formats 1-2 wrote
the older spellings (``basewrench``, ``momentum``, ``rnea-basewrench``). An older file still
loads and predicts as before: :func:`read_older_spellings` maps its names once (``load_model``
calls it), and ``model_upgrade.upgrade_model`` rewrites the folder in format 3.

A pure translation of a config dict, below the model (``trained_model.py``) and the upgrade
(``model_upgrade.py``), which both use it.
"""
from __future__ import annotations

import warnings

from ..analytic.method_names import estimator_name
from ..deprecation import DeprecatedNameWarning

FIRST_CANONICAL_FORMAT = 3  # the first model format that writes the canonical estimator names


def older_spellings(config: dict) -> dict:
    """``{where: (spelled, canonical)}`` for each estimator name ``config`` (a config.json) spells the old way."""
    found = {}
    places = (("preset.prior", (config.get("preset") or {}).get("prior")),
              ("prior.kind", (config.get("prior") or {}).get("kind")))
    for where, name in places:
        if isinstance(name, str):
            canonical = estimator_name(name, warn=False)  # an unknown name is refused here, named
            if canonical != name:
                found[where] = (name, canonical)
    return found


def read_older_spellings(config: dict, model_dir) -> dict:
    """``config`` with its estimator names canonical; a warning when an older file spelled them otherwise."""
    found = older_spellings(config)
    if not found:
        return config
    names = ", ".join(f"{where} {old!r} (now {new!r})" for where, (old, new) in found.items())
    warnings.warn(f"model {model_dir} is model format {config.get('format_version', 1)}, which spells the "
                  f"estimators the old way: {names}. It loads and predicts as before; "
                  f"hybrid_dyn.learn.model_upgrade.upgrade_model({str(model_dir)!r}) rewrites it in format "
                  f"{FIRST_CANONICAL_FORMAT} (the same weights and training fingerprint)",
                  DeprecatedNameWarning, stacklevel=3)
    config = {**config, "preset": dict(config["preset"])}
    if "preset.prior" in found:
        config["preset"]["prior"] = found["preset.prior"][1]
    if "prior.kind" in found:
        config["prior"] = {**config["prior"], "kind": found["prior.kind"][1]}
    return config
