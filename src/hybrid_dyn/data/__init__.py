"""Datasets: the on-disk format, loading, splits and sliding windows."""
from .dataset import (
    FIELD_UNITS, SPLITS, Dataset, DatasetError, Instance, load_dataset, package_versions, read_manifest,
    split_by_instance, write_instance, write_manifest,
)
from .windows import WindowedSplit

__all__ = [
    "FIELD_UNITS", "SPLITS", "Dataset", "DatasetError", "Instance", "WindowedSplit", "load_dataset",
    "package_versions", "read_manifest", "split_by_instance", "write_instance", "write_manifest",
]
