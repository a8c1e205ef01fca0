"""Did a refactor change what the toolkit computes? Compare two checkouts that ran the same bench.

Run the same bench in two checkouts (the old code and the new), each with its own caches, e.g.
    (cd OLD && hybrid-dyn bench --profile quick --out reports/quick)
    (cd NEW && hybrid-dyn bench --profile quick --out reports/quick)
then
    .venv/bin/python checks/same_outputs.py OLD NEW --report reports/quick

It compares, byte for byte:
- every dataset under ``data/`` (each file's SHA-256: the HDF5 arrays and the manifests, whose package
  versions and paths are the same when both ran on one machine);
- every trained model under ``runs/``, matched by its path, which holds its training fingerprint: its
  ``config.json`` but for the display setting ``progress`` (a bench of one worker shows the training
  bars, of several not), and the tensors of ``model.safetensors`` by name, dtype and value (its metadata
  holds the config's digest); ``timing.json`` holds wall-clock times and is left out;
- the report's ``results.csv`` but for the columns that are measured times;
- every array of the report's ``predictions.h5`` (NaN, a refused sample, equal to NaN).

Exit status 0 when all are identical, 1 when anything differs (each difference printed).
"""
from __future__ import annotations

import argparse
import csv
import hashlib
import json
import sys
from pathlib import Path

import h5py
import numpy as np

# results.csv columns that are measured times, not results.
TIMING_COLUMNS = {"train_seconds", "infer_us_per_sample", "infer_us_per_call", "train_cpu_seconds", "score_cpu_seconds"}


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _files(root: Path, names: tuple[str, ...] | None = None) -> dict[str, str]:
    if not root.is_dir():
        return {}
    return {p.relative_to(root).as_posix(): _sha(p) for p in sorted(root.rglob("*"))
            if p.is_file() and (names is None or p.name in names)}


def _compare_files(what: str, a: dict, b: dict, out: list) -> int:
    for key in sorted(set(a) | set(b)):
        if a.get(key) != b.get(key):
            out.append(f"{what} {key}: " + ("missing in one" if key not in a or key not in b else "differs"))
    return len(set(a) | set(b))


def _without_display(doc):
    """A model config without its ``progress`` entries: whether training bars were drawn, not what was trained."""
    if isinstance(doc, dict):
        return {k: _without_display(v) for k, v in doc.items() if k != "progress"}
    if isinstance(doc, list):
        return [_without_display(v) for v in doc]
    return doc


def _models(root: Path) -> dict:
    """Per model file under ``root``: what it computes (the config without display settings, the tensors)."""
    from safetensors.numpy import load_file

    out = {}
    for p in sorted(root.rglob("*")) if root.is_dir() else []:
        key = p.relative_to(root).as_posix()
        if p.name == "config.json":
            out[key] = json.dumps(_without_display(json.loads(p.read_text())), sort_keys=True)
        elif p.name == "model.safetensors":
            tensors = load_file(p)
            out[key] = hashlib.sha256(b"".join(name.encode() + str(t.dtype).encode() + str(t.shape).encode()
                                               + np.ascontiguousarray(t).tobytes()
                                               for name, t in sorted(tensors.items()))).hexdigest()
    return out


def _results(path: Path) -> dict:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {(r["task"], r["scenario"], r["model"]): {k: v for k, v in r.items() if k not in TIMING_COLUMNS}
            for r in rows}


def _arrays(path: Path) -> dict:
    found = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: found.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return found


def _same_array(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    nan_equal = a.dtype.kind in "fc" and b.dtype.kind in "fc"
    return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=nan_equal))


def compare(old: Path, new: Path, report: str) -> list[str]:
    out = []
    n_data = _compare_files("dataset file", _files(old / "data"), _files(new / "data"), out)
    n_models = _compare_files("model file", _models(old / "runs"), _models(new / "runs"), out)
    ra, rb = _results(old / report / "results.csv"), _results(new / report / "results.csv")
    for key in sorted(set(ra) | set(rb)):
        if ra.get(key) != rb.get(key):
            diff = [c for c in (ra.get(key) or rb.get(key)) if (ra.get(key) or {}).get(c) != (rb.get(key) or {}).get(c)]
            out.append(f"results.csv row {'/'.join(key)}: differs in {', '.join(diff)}")
    pa, pb = _arrays(old / report / "predictions.h5"), _arrays(new / report / "predictions.h5")
    for name in sorted(set(pa) | set(pb)):
        if name not in pa or name not in pb or not _same_array(pa[name], pb[name]):
            out.append(f"predictions.h5 {name}: differs or missing in one")
    print(f"compared {n_data} dataset files, {n_models} model files, {len(ra)} result rows (timing columns left out), "
          f"{len(pa)} prediction arrays")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", type=Path, help="the checkout of the old code, after its bench")
    ap.add_argument("new", type=Path, help="the checkout of the new code, after the same bench")
    ap.add_argument("--report", default="reports/quick", help="the report folder, relative to each checkout")
    args = ap.parse_args(argv)
    diffs = compare(args.old, args.new, args.report)
    print("\n".join(diffs) if diffs else "identical")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
