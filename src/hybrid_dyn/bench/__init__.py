"""The benchmark harness: analytic vs identified vs learned vs hybrid on the same data."""
from .metrics import ErrorReport, nmse, rmse, rmse_per_component
from .profiles import PROFILES, BenchProfile, get_profile
from .rows import FAMILIES, ROWS, Row, declare
from .results import COLUMNS
from .runner import run_bench

__all__ = ["COLUMNS", "FAMILIES", "PROFILES", "ROWS", "BenchProfile", "ErrorReport", "Row", "declare", "get_profile",
           "nmse", "rmse", "rmse_per_component", "run_bench"]
