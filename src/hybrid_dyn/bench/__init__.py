"""The benchmark harness: analytic vs identified vs learned vs hybrid on the same data."""
from .metrics import ErrorReport, nmse, rmse, rmse_per_component
from .families import FAMILIES, Family
from .profiles import PROFILES, BenchProfile
from .results import COLUMNS
from .rows import ROWS, Row
from .runner import run_bench

__all__ = ["COLUMNS", "FAMILIES", "PROFILES", "ROWS", "BenchProfile", "ErrorReport", "Family", "Row",
           "nmse", "rmse", "rmse_per_component", "run_bench"]
