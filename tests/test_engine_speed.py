"""The identification's evaluation without its Python overhead gives the same numbers to the last
bit: a family's batch of parameter sets built from each element's kept compilation
(:mod:`droptower.identify.families.compiled`) is the stack of each row's coupling file parsed
anew, and the engine's vectorised optimised variables (:class:`~droptower.identify.engine.problem.Variables`)
are :meth:`~droptower.identify.engine.problem.FitVariable.to_value` and ``to_z`` of each number.
Bits are compared (``view(uint64)``), not values within a tolerance. (The fits' own numbers:
tests/test_engine_regression.py.)"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from droptower.errors import DroptowerError
from droptower.identify.data import DataScale
from droptower.identify.engine.problem import FitVariable, Variables, admissible_couplings
from droptower.identify.families import family_class
from droptower.identify.families.compiled import ElementCache, frozen, stacked
from droptower.rheology import Coupling, parse_coupling

SCALE = DataScale(0.02, 0.02, 200.0, 1e4, 1.0, 30.0)
#: Families and options whose couplings hold every element kind the drop and servo fits use.
CASES = [("masing", None), ("masing", {"constriction": True}), ("filled_rubber", {"n": 8}),
         ("filled_rubber", {"n": 4, "large_strain": True}), ("elastoslide", None), ("zerodim6", None),
         ("zerodim20", None), ("pfeffer", None), ("template", None)]


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def _rows(fam, rng: np.random.Generator, m: int) -> np.ndarray:
    """``m`` parameter sets drawn over the bounds (optimised variables), with a Jacobian's
    columns around the first (one parameter moved each: the cache's case)."""
    lo, hi = np.array([p.z_bounds() for p in fam.parameters]).T
    z = lo + rng.random((m, lo.size)) * (hi - lo)
    rows = np.array([[p.to_value(v) for p, v in zip(fam.parameters, r)] for r in z])
    for i, values in fam.choices().items():  # a parameter of a few values (the elastoslide's odd p)
        rows[:, i] = rng.choice(values, m)
    shifted = np.repeat(rows[:1], lo.size, axis=0)
    shifted[np.arange(lo.size), np.arange(lo.size)] *= 1.0 + 1e-6
    return np.concatenate([rows, shifted, rows[:2]])  # rows met before, again


def _old_batch(fam, rows: np.ndarray) -> Coupling:
    """The batch as it was built before: every row's coupling file parsed, the couplings stacked
    by compiling the first's elements again."""
    couplings = [parse_coupling(fam.coupling_data(v)) for v in rows]
    first = couplings[0]
    return Coupling(first.elements, name=first.name, description=first.description, source=first.source,
                    units=first.units, path=first.path, params=np.vstack([c.params for c in couplings]))


@pytest.mark.parametrize("kind,options", CASES)
def test_a_batch_is_the_stack_of_each_rows_coupling_to_the_last_bit(kind, options):
    fam = family_class(kind)(SCALE, options)
    rows = np.array([r for r in _rows(fam, np.random.default_rng(7), 4) if _admissible(fam, r)])
    assert len(rows) >= len(fam.parameters)
    for _ in range(2):  # the second time every element is kept from the first
        old, new = _old_batch(fam, rows), fam.batch(rows)
        assert np.array_equal(_bits(new.params), _bits(old.params))
        for name in ("codes", "p_off", "s_off", "kernel_owner"):
            assert np.array_equal(getattr(new, name), getattr(old, name)), name
        assert (new.name, new.description, new.source, new.units, new.path) == \
               (old.name, old.description, old.source, old.units, old.path)
        assert [e.model_dump() for e in new.elements] == [e.model_dump() for e in old.elements]
        assert all(a.code == b.code and np.array_equal(_bits(a.params), _bits(b.params))
                   for a, b in zip(new.kernels, old.kernels))


def _admissible(fam, v) -> bool:
    try:
        fam.coupling(v)
        return True
    except DroptowerError:
        return False


def test_a_refused_row_is_refused_in_a_batch_and_marked_as_alone():
    """A row whose element the file's validation refuses (a falling cubic spring: b < 0) makes the
    batch refuse, however often its other elements were kept; the engine's fallback then marks
    that row alone, the others' numbers unchanged."""
    fam = family_class("masing")(SCALE)
    good = fam.initial()
    bad = good.copy()
    bad[fam.names.index("b_nm_per_rad")] = -1.0
    with pytest.raises(DroptowerError):
        fam.coupling(bad)
    fam.batch(good[None])  # every element of the good row kept
    with pytest.raises(DroptowerError):
        fam.batch(np.array([good, bad]))
    coupling, ok = admissible_couplings(fam, np.array([good, bad, good]))
    assert ok.tolist() == [True, False, True]
    assert np.array_equal(_bits(coupling.params[0]), _bits(fam.coupling(good).params[0]))


def test_structures_that_differ_are_refused_as_the_stack_refuses_them():
    small, large = (family_class("masing")(SCALE, {"n": n}) for n in (3, 5))
    files = [small.coupling_data(small.initial()), large.coupling_data(large.initial())]
    with pytest.raises(DroptowerError, match="same element structure"):
        stacked(files)
    with pytest.raises(DroptowerError, match="same element structure"):
        Coupling.stack([parse_coupling(f) for f in files])


def test_the_cache_keeps_at_most_its_size_and_tells_every_bit_apart():
    cache = ElementCache(size=3)
    fam = family_class("zerodim6")(SCALE)
    rows = np.repeat(fam.initial()[None], 5, axis=0) * (1.0 + 1e-9 * np.arange(5))[:, None]
    coupling = stacked([fam.coupling_data(v) for v in rows], cache)
    assert len(cache) == 3
    assert np.array_equal(_bits(coupling.params), _bits(_old_batch(fam, rows).params))
    assert frozen(0.0) != frozen(-0.0) and frozen(1.0) != frozen(np.float64(1.0)) and frozen(1) != frozen(1.0)
    assert frozen({"a": [1.0, {"p": 2.0}]}) == frozen({"a": [1.0, {"p": 2.0}]})


#: Parameters of every kind the families declare: logarithmic, and linear from 0 with a scale.
PARAMETERS = [FitVariable("k", 1e-3, 1e7), FitVariable("a", 0.0, 1e3, log=False, scale=37.5),
              FitVariable("tau", 1e-9, 1e3), FitVariable("alpha", 0.0, 30.0, log=False),
              FitVariable("g", 0.0, 1e12, log=False, scale=3.3e7)]


@settings(max_examples=60, derandomize=True, deadline=None)
@given(st.lists(st.lists(st.floats(0.0, 1.0), min_size=len(PARAMETERS), max_size=len(PARAMETERS)),
                min_size=1, max_size=6),
       st.lists(st.booleans(), min_size=len(PARAMETERS), max_size=len(PARAMETERS)))
def test_vectorised_optimised_variables_are_each_numbers_own(units, free):
    idx = np.flatnonzero(free) if any(free) else np.arange(len(PARAMETERS))
    lo, hi = np.array([PARAMETERS[i].z_bounds() for i in idx]).T
    z = lo + np.array(units)[:, idx] * (hi - lo)
    variables = Variables(PARAMETERS, idx)
    values = variables.values(z)
    one_by_one = np.array([[PARAMETERS[i].to_value(zi) for i, zi in zip(idx, row)] for row in z])
    assert np.array_equal(_bits(values), _bits(one_by_one))
    full = np.ones((len(z), len(PARAMETERS)))
    full[:, idx] = values
    back = np.array([[PARAMETERS[i].to_z(v[i]) for i in idx] for v in full])
    assert np.array_equal(_bits(variables.z(full)), _bits(back))


def test_vectorised_exp_and_log_are_the_scalar_ones_over_many_decades():
    """numpy's exp and log of an array, element by element, are those of each number alone (the
    engine's vectorised variables rest on it): numbers spread over the doubles' range and around 0."""
    rng = np.random.default_rng(3)
    z = np.concatenate([rng.uniform(-700.0, 700.0, 20_000), rng.normal(0.0, 3.0, 20_000)])
    assert np.array_equal(_bits(np.exp(z)), _bits([float(np.exp(x)) for x in z]))
    v = np.exp(z)
    assert np.array_equal(_bits(np.log(v)), _bits([float(np.log(x)) for x in v]))
