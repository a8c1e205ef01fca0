"""What every declared row, family, profile and study must hold: parametrized over the registries, so that a
new declaration (the toolkit's, a plugin's imported with the catalogue) is tested without an edit here."""
import json

import pytest

from hybrid_dyn.bench.catalog import ROWS
from hybrid_dyn.bench.families import FAMILIES
from hybrid_dyn.bench.plan import BenchPlan
from hybrid_dyn.bench.profiles import PROFILES, BenchProfile
from hybrid_dyn.bench.rows import TASK_TARGET
from hybrid_dyn.bench.studies import STUDIES
from hybrid_dyn.data import FIELD_UNITS
from hybrid_dyn.description import ROBOTS

FIGURES = ("traces", "error-vs-force")  # what report_figures.py draws per family
ANY = BenchProfile(name="t", scenarios=("s",))  # a plan with no scenario restrictions


def _data(fields, robot="panda"):
    """What the bench reads of a dataset to choose its rows: its fields and its robot's name."""
    return type("Data", (), {"fields": list(fields), "meta": {"robot": robot}})()


@pytest.mark.parametrize("name", list(ROWS))
def test_a_row_runs_where_its_fields_are_and_is_skipped_naming_a_missing_one(name):
    row = ROWS[name]
    assert row.family in FAMILIES and TASK_TARGET[row.task] in row.needs
    assert set(row.needs) <= set(FIELD_UNITS)
    plan = BenchPlan(ANY)
    every = _data(FIELD_UNITS)
    assert plan.skip_reason(row, every) is None
    for field in row.needs:
        reason = plan.skip_reason(row, _data(f for f in FIELD_UNITS if f != field))
        assert reason is not None and field in reason, (field, reason)
    reason = plan.skip_reason(row, _data(FIELD_UNITS, robot=ROBOTS.names(data_only=True)[0]))
    assert (reason is not None and "URDF" in reason) == row.needs_urdf, reason


@pytest.mark.parametrize("name", list(ROWS))
def test_a_rows_metadata_agrees_with_its_family_and_its_prior(name):
    row = ROWS[name]
    if row.trains:  # a trained row has a loss curve: its family is fitted to data
        assert FAMILIES[row.family].fitted
    if row.prior_row is not None:  # the hybrid's physics prior is a physics row of the same task
        prior, family = ROWS[row.prior_row], FAMILIES[ROWS[row.prior_row].family]
        assert prior.task == row.task and not prior.trains and prior.prior_row is None
        assert not family.fitted or family.identifies_parameters  # physics: nominal, or identified parameters
    assert row.reference is None or (isinstance(row.reference, str) and row.reference)


@pytest.mark.parametrize("name", list(FAMILIES))
def test_a_family_has_rows_and_consistent_metadata(name):
    family = FAMILIES[name]
    assert ROWS.where(family=name), "a family no row belongs to"
    assert set(family.figures) <= set(FIGURES)
    assert family.fitted or not (family.physics_informed or family.identifies_parameters)
    assert [r.name for r in ROWS.where(family=name)] == [r.name for r in BenchPlan(
        BenchProfile(name="t", scenarios=("s",), families=(name,))).selected_rows()]


@pytest.mark.parametrize("name", list(PROFILES))
def test_a_profile_names_its_families_and_rows_and_records_itself_in_json(name):
    profile = PROFILES[name]
    assert profile.families or profile.rows
    assert set(profile.families) <= set(FAMILIES) and set(profile.rows) <= set(ROWS)
    BenchPlan(profile).check()
    recorded = json.loads(json.dumps(profile.to_dict()))
    assert recorded == profile.to_dict() and recorded["name"] == name
    assert BenchPlan(profile).selected_rows(), "a profile that runs no row"


@pytest.mark.parametrize("name", list(STUDIES))
def test_a_study_stands_on_a_declared_profile_and_each_variant_is_a_profile_of_its_own(name):
    study = STUDIES[name]
    assert study.base_profile() is PROFILES[study.profile]
    names = {study.variant_profile(v, ()).name for v in study.variants}
    assert len(names) == len(study.variants) and study.profile not in names  # a variant's report is its own
