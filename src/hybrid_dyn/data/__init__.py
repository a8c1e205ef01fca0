"""Datasets: the on-disk format, loading, splits and sliding windows."""
from .dataset import (
    FIELD_UNITS, SPLITS, Dataset, DatasetError, Instance, load_dataset, package_versions, read_manifest,
    split_by_instance, write_instance, write_manifest,
)
from .logs.importer import ImportReport, LogImportError, LogSpec, RowIssue, import_log, read_spec
from .logs.real_logs import REAL_SETS, real_dataset
from .input_windows import WindowedSplit

__all__ = [
    "FIELD_UNITS", "REAL_SETS", "SPLITS", "Dataset", "DatasetError", "ImportReport", "Instance", "LogImportError",
    "LogSpec", "RowIssue", "WindowedSplit", "import_log", "load_dataset", "read_spec", "real_dataset",
    "package_versions", "read_manifest", "split_by_instance", "write_instance", "write_manifest",
]
