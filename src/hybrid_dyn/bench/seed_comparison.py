"""Old name of the comparison with the 2021 paper, now in :mod:`hybrid_dyn.bench.reference_study`: its names
still served, with a warning."""
from __future__ import annotations

from .reference_study import old_module_names

__getattr__ = old_module_names(__name__, {"SEED_COMPARISON_FILE": "REFERENCE_COMPARISON_FILE",
                                          "seed_comparison_text": "reference_comparison_text",
                                          "comparison": "comparison", "ARCHITECTURES": "ARCHITECTURES",
                                          "TORQUE_NETS": "TORQUE_NETS"})
