"""Coverage of the model route's expanded uncertainties on virtual campaigns (the scaled-down
version of benchmarks/bench_uncertainty_coverage.py; tests/coverage_campaigns.py): one rig per
campaign drawn from its stated uncertainties, shared by its drops (J per fixture, the clock),
the extraction on the nominal rig. The 95 % intervals of the route's K' and loss factor hold the
truth in 95 % ± 2.5 % of 400 campaigns; the fit's intervals alone miss K' almost always (J's 1 %
does not average out over the drops) and the loss factor often (the clock)."""
import functools

import pytest

from coverage_campaigns import coverage


@functools.lru_cache(maxsize=None)
def _shares() -> dict[str, float]:
    return coverage(400, seed=20261128)


@pytest.mark.slow  # 400 campaigns of 6 drops (~5 s idle)
@pytest.mark.parametrize("name", ["k", "eta"])
def test_the_route_intervals_cover_the_truth(name):
    # binomial standard deviation over 400 campaigns: 1.1 %
    assert _shares()[name] == pytest.approx(0.95, abs=0.025)


@pytest.mark.slow
def test_the_fit_alone_under_covers():
    assert _shares()["k_fit"] < 0.2
    assert _shares()["eta_fit"] < 0.8
