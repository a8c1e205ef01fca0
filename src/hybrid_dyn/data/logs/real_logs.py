"""The real-robot logs (KUKA LWR, Baxter, SARCOS, a Franka Panda) as toolkit datasets.

Their import specs ship inside the package, ``hybrid_dyn/resources/real/*.toml``
(package data, so an installed toolkit has them; or the folder named by
``HYBRID_DYN_REAL_SPECS``). The KUKA, Baxter and SARCOS logs ship beside them in
``resources/real/logs`` (4.7 MB). The Panda log does not ship (its source repository
is GPL-3.0): it is read from ``../shared/data/real`` beside a checkout of the
repository. ``HYBRID_DYN_REAL_LOGS`` (a folder) overrides where the logs are.
:func:`real_dataset` imports a set once and caches it under a key made of the spec,
the importer version and the log files' checksums, so a changed spec or log is
re-imported and an unchanged one is not. A set whose log is absent raises
:class:`RealLogMissingError`, whose message says where to get it;
:func:`missing_real_log` gives that message without importing anything (the bench
skips such a scenario with it).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path


from ...deprecation import warn_renamed
from ...registry import Registry
from ...resources import resource_dir
from ..dataset import DatasetError, load_dataset
from .importer import import_log, read_spec, spec_checksum

_SHIPPED = "they ship with the package, in hybrid_dyn/resources/real/logs"


@dataclass(frozen=True)
class RealSet:
    """A real-robot log set, declared once in :data:`REAL_SETS`: its name (a bench scenario), its import
    spec's file in :func:`real_specs_dir`, and where its log comes from (said when the log is absent)."""

    name: str
    spec: str
    source: str = _SHIPPED


# A new set: its spec file in resources/real, and one declaration here.
REAL_SETS = Registry("real dataset", DatasetError)
for _set in (
    RealSet("real-kuka", "kuka.toml"),
    RealSet("real-baxter", "baxter.toml"),
    RealSet("real-sarcos", "sarcos.toml"),
    RealSet("real-panda", "panda.toml", source=(
        "it does not ship with the repository (its source is GPL-3.0): it is the project's shared data "
        "file ../shared/data/real/panda_gaz_exciting_traj1.csv beside a checkout of the repository, or build it from "
        "https://github.com/marcocognetti/FrankaEmikaPandaDynModel, folder "
        "matlab/data/Exciting_Traj/Trajectory_1/rbt_log/ (its four text files side by side as columns "
        "t, q1..q7, qd1..qd7, tau1..tau7 with that header; ../shared/data/real/README.md)")),
):
    REAL_SETS.register(_set)


def __getattr__(name):
    # REAL_LOG_SOURCES: the hand-kept table before each set declared its source.
    if name == "REAL_LOG_SOURCES":
        warn_renamed("name", f"{__name__}.REAL_LOG_SOURCES", f"{__name__}.REAL_SETS[name].source", stacklevel=2)
        return {s.name: s.source for s in REAL_SETS.values()}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class RealLogMissingError(DatasetError):
    """A real set's log file is not where its spec looks: the scenario cannot run (the bench skips it)."""

    def __init__(self, name: str, missing: list):
        self.scenario, self.missing = name, list(missing)
        super().__init__(f"{name}: log file(s) {self.missing} not found; {REAL_SETS[name].source if name in REAL_SETS else _SHIPPED}; "
                         f"or set HYBRID_DYN_REAL_LOGS to the folder that holds them")


def real_specs_dir() -> Path:
    """Where the import specs of the real sets are: ``$HYBRID_DYN_REAL_SPECS``, else the ones that ship
    inside the package (``hybrid_dyn/resources/real``, package data)."""
    env = os.environ.get("HYBRID_DYN_REAL_SPECS")
    return Path(env) if env else resource_dir("real")


def real_spec_path(name: str) -> Path:
    if name not in REAL_SETS:
        raise DatasetError(f"unknown real dataset {name!r}; known: {sorted(REAL_SETS)}")
    path = real_specs_dir() / REAL_SETS[name].spec
    if not path.is_file():
        raise DatasetError(f"import spec for {name} not found at {path}; set HYBRID_DYN_REAL_SPECS to the folder "
                           f"holding {REAL_SETS[name].spec}")
    return path


def missing_real_log(name: str) -> str | None:
    """Why the real set ``name`` cannot be imported here (its log is absent, and where to get it), or None."""
    spec = read_spec(real_spec_path(name))
    missing = [str(f) for f in spec.files if not Path(f).is_file()]
    return str(RealLogMissingError(name, missing)) if missing else None


def real_dataset(name: str, cache_dir, /, log=None, **spec_overrides) -> Path:
    """The dataset directory of the real set ``name`` (a key of :data:`REAL_SETS`),
    imported into ``cache_dir`` on first use and reused after.

    ``spec_overrides``: fields of its :class:`LogSpec` to change for this import
    (e.g. ``trajectories="blocks", n_blocks=4``, or another ``name`` for its
    manifest); they enter the cache key. An absent log raises :class:`RealLogMissingError`.
    """
    spec = replace(read_spec(real_spec_path(name)), **spec_overrides)
    missing = [str(f) for f in spec.files if not Path(f).is_file()]
    if missing:
        raise RealLogMissingError(name, missing)
    path = Path(cache_dir) / f"{name}-{spec_checksum(spec)[:16]}"
    if (path / "manifest.json").is_file():
        try:
            load_dataset(path, verify=True)
            return path
        except DatasetError as err:  # corrupt or partial cache: import again
            if log:
                log(f"{name}: cached import unusable ({err}); importing again")
    report = import_log(spec, path, overwrite=True)
    if log:
        log(report.text(3))
    return path
