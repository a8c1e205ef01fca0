"""Old name of :mod:`hybrid_dyn.bench.reference_study` (the 2021 paper's tables): its names still served, with a warning."""
from __future__ import annotations

from .reference_study import old_module_names

__getattr__ = old_module_names(__name__, {"SEED_TABLE1": "REFERENCE_TABLE1", "SEED_TABLE2": "REFERENCE_TABLE2",
                                          "SEED_TABLE3": "REFERENCE_TABLE3", "seed_dataset_label": "reference_dataset_label",
                                          "GAZ2019_VALIDATION_RMSE": "GAZ2019_VALIDATION_RMSE"})
