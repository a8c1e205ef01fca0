"""Model files of an older format, upgraded in place: :func:`upgrade_model`.

Formats 1-2 spelled the analytic prior's estimator the old way (``model_spellings.py``, which
also reads them when such a file is loaded, with a warning that names this upgrade). The upgrade
rewrites the folder in format 3 with canonical names: the same weights and training fingerprint,
so a bench or ``train`` run still reuses it. It sits above the model (it loads and saves one);
nothing below imports it.
"""
from __future__ import annotations

import warnings
from pathlib import Path

from ..deprecation import DeprecatedNameWarning
from ..outputs import output_lock
from .model_file import recorded_train_cpu
from .model_spellings import FIRST_CANONICAL_FORMAT, older_spellings, read_older_spellings  # noqa: F401  (re-exported)
from .trained_model import MODEL_FORMAT_VERSION, load_model, save_model


def upgrade_model(model_dir) -> bool:
    """Rewrite the model folder ``model_dir`` in the current model format with canonical estimator names.

    The weights, the training fingerprint and every other field stay; the digests in the weights'
    metadata and timing.json are written again for the new config.json (``trained_model.save_model``, each
    file atomically). Returns whether anything was rewritten (False: already canonical). Holds the
    folder's output lock, so it never races a training run there.
    """
    model_dir = Path(model_dir)
    with output_lock(model_dir, "model folder"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecatedNameWarning)  # the warning this function answers
            model = load_model(model_dir)  # every digest checked before anything is written
        if model.config.get("format_version") == MODEL_FORMAT_VERSION and not older_spellings(model.config):
            return False
        config = {**model.config, "format_version": MODEL_FORMAT_VERSION}
        seconds, cpu = model.train_seconds, recorded_train_cpu(model)  # read under the old config's digest
        save_model(model.module, config, model_dir, None if seconds != seconds else seconds,  # NaN: no timing
                   None if cpu != cpu else cpu)
    return True
