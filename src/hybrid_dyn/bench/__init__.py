"""The benchmark harness: analytic vs identified vs learned vs hybrid on the same data."""
from .metrics import ErrorReport, nmse, rmse, rmse_per_component
from .profiles import PROFILES, BenchProfile, get_profile
from .runner import COLUMNS, run_bench

__all__ = ["COLUMNS", "PROFILES", "BenchProfile", "ErrorReport", "get_profile", "nmse", "rmse",
           "rmse_per_component", "run_bench"]
