"""The premise of tests/shared_fits.py: a fit repeated with the same arguments is the same fit
(seeded searches, fixed data), and the cache fits anew whenever any argument differs."""
from __future__ import annotations

import numpy as np

from droptower.identify import dropfit, strategies
from droptower.identify.droplogs import ReadSettings, read_decays
from droptower.rheology import parse_coupling
from droptower.rig.config import load_rig
from droptower.rig.simulate import DropTest, simulate
from random_couplings import random_truth, servo_records
from shared_fits import FitCache, share_fits


def _same(a, b) -> None:
    assert list(a.parameters) == list(b.parameters)
    assert np.array_equal(list(a.parameters.values()), list(b.parameters.values()))
    assert repr(a.fit_error) == repr(b.fit_error) and a.evaluations == b.evaluations and a.verdict.verdict == b.verdict.verdict


def test_a_repeated_servo_fit_and_drop_fit_are_the_same_fit(tmp_path):
    records = servo_records(parse_coupling(random_truth("pfeffer", np.random.default_rng(27))), 27)
    _same(strategies.identify("pfeffer", records), strategies.identify("pfeffer", records))
    coupling = parse_coupling(random_truth("pfeffer", np.random.default_rng(28)))
    tests = [DropTest(0.359, 2.0, h, 0.0, 0, 70 + i) for i, h in enumerate((0.3, 1.5))]
    paths = [r.write_log(tmp_path / f"t{i}.parquet") for i, r in enumerate(simulate(load_rig("rapp2022"), coupling,
                                                                                    tests, 0.08))]
    decays, _ = read_decays(paths, ReadSettings())
    settings = dropfit.DropFitSettings(holdout_fraction=0.0, max_nfev=20)
    _same(*(dropfit.identify_drops("pfeffer", decays, settings=settings) for _ in range(2)))


def test_the_cache_fits_anew_when_any_argument_differs():
    calls = []

    def servo(kind, segments, **kw):
        calls.append(kind)
        return {"kind": kind}

    cache = FitCache(servo, servo)
    records = servo_records(parse_coupling(random_truth("pfeffer", np.random.default_rng(27))), 27)
    other = [records[0]] + records[2:]
    cache.servo("pfeffer", records)
    assert cache.servo("pfeffer", list(records), options={}, init=None) == {"kind": "pfeffer"}  # the same call
    cache.servo("pfeffer", records, options={"max_nfev": 0, "substeps": 1})  # the defaults: the same call too
    for kw in ({"options": {"x": 1}}, {"options": {"max_nfev": 5}}, {"holdout": records[:1]}, {"seed": 1}, {"search": "always"},
               {"init": {"k1_nm_per_rad": 1.0}}):
        cache.servo("pfeffer", records, **kw)
    cache.servo("pfeffer", other)
    cache.servo("zerodim6", records)
    assert cache.calls == 11 and cache.fits == len(calls) == 9
    first = cache.servo("pfeffer", records)
    first["kind"] = "changed"  # a caller's copy: the next caller gets the fit as made
    assert cache.servo("pfeffer", records) == {"kind": "pfeffer"}


def test_share_fits_routes_the_library_and_restores_it():
    before = strategies.identify, dropfit.identify_drops
    with share_fits() as cache:
        assert strategies.identify == cache.servo and dropfit.identify_drops == cache.drop
    assert (strategies.identify, dropfit.identify_drops) == before
