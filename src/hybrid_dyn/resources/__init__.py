"""Data files that ship inside the package (package data), found through importlib.resources.

- ``robots/``: the robot descriptions (``<name>.toml``, each declared in ``description/robots.py``) and
  their published parameter sets (``params/*.json``); read by :mod:`hybrid_dyn.description`.
- ``real/``: the import specs of the real-robot logs (``*.toml``) and the three public logs
  that ship with them (``real/logs``, 4.7 MB); read by :mod:`hybrid_dyn.data.logs.real_logs`.
- ``bench/``: the bench's profiles and studies, declared as data (``profiles.toml``, ``studies.toml``);
  read by :mod:`hybrid_dyn.bench.profiles` and :mod:`hybrid_dyn.bench.studies`.

They live here rather than at the repository's root so that an installed toolkit (a wheel,
``pip install .``) carries them: they were once found through the source file's
``parents[2]``, which only exists in a checkout.
"""
from __future__ import annotations

import importlib.resources
from pathlib import Path


def resource_dir(name: str) -> Path:
    """The folder ``name`` (``"robots"``, ``"real"`` or ``"bench"``) of the installed package, as a filesystem path.

    Descriptions name their files relative to themselves (a parameter JSON beside the TOML, a log
    beside its spec), so the folder must be a real one: a package imported from a zip archive is refused.
    """
    root = importlib.resources.files(__name__)
    if not isinstance(root, Path):  # a zipimport Traversable: nothing here could be opened by path
        raise RuntimeError(f"hybrid_dyn's package data ({root}) is not on the file system; install the "
                           f"package unzipped (pip installs wheels unzipped)")
    return root / name
