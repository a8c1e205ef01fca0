"""The bench's families, declared once in :data:`FAMILIES` (this module is their catalogue).

A row belongs to exactly one family (``rows.Row.family``). The families are declared in the order the
report's figures list them; every list of families (the studies', ``compare``'s, the figures') is read
from their metadata with ``FAMILIES.names(field=value)``. A profile never reads it: each names its
families (``resources/bench/profiles.toml``), so a family declared later changes no shipped profile.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import UsageError
from ..registry import Registry


@dataclass(frozen=True)
class Family:
    """A family of bench rows.

    fitted: its rows are fitted to data (networks, or parameters identified from data); physics_informed:
    a fitted family with physics inside (the report's torque floor); identifies_parameters: its rows fit
    the robot's physical parameters (``compare`` leaves them out: their ratio to physics is no network's
    data limit); in_studies: a study picks its best trained row, and ``compare`` reads it; figures: the
    report's figures that draw its best row ("traces", "error-vs-force").
    """

    name: str
    description: str
    fitted: bool
    physics_informed: bool = False
    identifies_parameters: bool = False
    in_studies: bool = False
    figures: tuple = ()


FAMILIES = Registry("bench family", UsageError)
for _family in (
    Family("analytic", "physics on the nominal model, nothing trained", fitted=False, in_studies=True,
           figures=("traces", "error-vs-force")),
    Family("seed-net", "the seed's networks (Kruzic et al. 2021, Tables 1 and 3)", fitted=True, in_studies=True,
           figures=("traces", "error-vs-force")),
    Family("residual", "a network that corrects an analytic part (physics-informed)", fitted=True,
           physics_informed=True, in_studies=True, figures=("traces", "error-vs-force")),
    Family("delan", "Deep Lagrangian networks (physics-informed)", fitted=True, physics_informed=True,
           in_studies=True, figures=("traces",)),
    Family("identified", "physics on parameters identified from data, and the residual nets on them", fitted=True,
           identifies_parameters=True, in_studies=True, figures=("traces",)),
    Family("learned", "other black-box networks", fitted=True),
    Family("gp", "Gaussian-process regression (scikit-learn fit, numpy predictions; not PyTorch)", fitted=True),
):
    FAMILIES.register(_family)
