"""Where a dataset is written: a local directory or any fsspec URL.

The detail (what it computes, the equations, why each choice): docs/design/data.md, section ``data/store.py``.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from ..errors import MissingDependencyError, UsageError
from ..outputs import unique_temp
from .dataset import DatasetError, check_manifest, is_url, sha256_file, sha256_stream  # dataset never imports store

__all__ = ["DatasetStore", "fetch_dataset", "is_url"]


class DatasetStore:
    """Files of one dataset under ``location`` (a path or an fsspec URL); paths are '/'-separated and relative."""

    def __init__(self, location):
        self.location = str(location)
        if is_url(self.location):
            try:
                import fsspec
            except ImportError as err:  # pragma: no cover - fsspec comes with torch
                raise MissingDependencyError("writing to a URL needs fsspec: pip install fsspec") from err
            self.fs, self.root = fsspec.core.url_to_fs(self.location)
            self.local = None
        else:
            self.fs, self.root = None, None
            self.local = Path(self.location)

    def __repr__(self) -> str:
        return f"DatasetStore({self.location!r})"

    # ------------------------------------------------------------- paths
    def _p(self, rel: str) -> str:
        return f"{self.root.rstrip('/')}/{rel}" if rel else self.root

    def local_path(self, rel: str = "") -> Path | None:
        """The local path of ``rel``, or None for a URL store."""
        return None if self.local is None else self.local / rel

    def lock_target(self) -> Path | None:
        """The local path a run locks (``outputs.output_lock``): the folder itself, also for a
        ``file://`` URL; None for a remote store, where flock cannot reach."""
        if self.local is not None:
            return self.local
        protocol = self.fs.protocol if isinstance(self.fs.protocol, tuple) else (self.fs.protocol,)
        return Path(self.root) if {"file", "local"} & set(protocol) else None

    # ------------------------------------------------------------- queries
    def exists(self, rel: str) -> bool:
        return (self.local / rel).exists() if self.local is not None else self.fs.exists(self._p(rel))

    def read_text(self, rel: str) -> str:
        if self.local is not None:
            return (self.local / rel).read_text()
        with self.fs.open(self._p(rel), "r") as f:
            return f.read()

    def sha256(self, rel: str) -> str:
        if self.local is not None:
            return sha256_file(self.local / rel)
        with self.fs.open(self._p(rel), "rb") as f:
            return sha256_stream(f)

    def entries(self) -> list[str]:
        """Names directly inside the store's folder (hidden ones included), sorted; [] if it does not exist."""
        if self.local is not None:
            return sorted(p.name for p in self.local.iterdir()) if self.local.is_dir() else []
        if not self.fs.exists(self.root):
            return []
        return sorted(p.rstrip("/").rsplit("/", 1)[-1] for p in self.fs.ls(self.root, detail=False))

    def glob(self, pattern: str) -> list[str]:
        """Relative paths matching a glob pattern, sorted."""
        if self.local is not None:
            return sorted(str(p.relative_to(self.local)) for p in self.local.glob(pattern))
        root = self.root.rstrip("/") + "/"
        return sorted(p[len(root):] if p.startswith(root) else p for p in self.fs.glob(self._p(pattern)))

    # ------------------------------------------------------------- writes
    def makedirs(self, rel: str = "") -> None:
        if self.local is not None:
            (self.local / rel).mkdir(parents=True, exist_ok=True)
        else:
            self.fs.makedirs(self._p(rel), exist_ok=True)

    def remove(self, rel: str) -> None:
        if self.local is not None:
            (self.local / rel).unlink(missing_ok=True)
        elif self.fs.exists(self._p(rel)):
            self.fs.rm(self._p(rel))

    def write_text(self, rel: str, text: str) -> None:
        """Write a small text file (atomically on a local disk)."""
        if self.local is not None:
            path = self.local / rel
            tmp = unique_temp(path)
            tmp.write_text(text)
            os.replace(tmp, path)
        else:
            with self.fs.open(self._p(rel), "w") as f:
                f.write(text)

    def put_file(self, local_file: Path, rel: str) -> None:
        """Move a finished local file into the store (atomically on a local disk)."""
        if self.local is not None:
            dest = self.local / rel
            tmp = unique_temp(dest)
            shutil.copyfile(local_file, tmp)
            os.replace(tmp, dest)
        else:
            self.fs.put_file(str(local_file), self._p(rel))

    def scratch_dir(self):
        """A local temporary directory for files on their way into the store."""
        return tempfile.TemporaryDirectory(prefix="hybrid-dyn-")


def fetch_dataset(url: str, local_dir) -> Path:
    """Copy a dataset from a URL store to ``local_dir`` (training reads local files); returns the path.

    Only what the manifest lists is copied, and ``load_dataset`` then checks
    every file against its checksum.
    """
    import json

    store = DatasetStore(url)
    if store.local is not None:
        raise UsageError(f"{url} is a local path, not a URL: load it with load_dataset directly")
    if not store.exists("manifest.json"):
        raise DatasetError(f"{url} has no manifest.json: not a dataset, or its generation never finished")
    meta = json.loads(store.read_text("manifest.json"))
    check_manifest(meta, f"{url}/manifest.json")  # before copying: a file must not land outside local_dir
    local = Path(local_dir)
    (local / "instances").mkdir(parents=True, exist_ok=True)
    for rec in meta["instances"]:
        dest = local / rec["file"]
        if not dest.exists():
            tmp = unique_temp(dest)
            store.fs.get_file(store._p(rec["file"]), str(tmp))
            os.replace(tmp, dest)
    tmp = unique_temp(local / "manifest.json")
    tmp.write_text(store.read_text("manifest.json"))
    os.replace(tmp, local / "manifest.json")
    return local
