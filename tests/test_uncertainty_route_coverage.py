"""Coverage of the model route's expanded uncertainties on virtual campaigns (the scaled-down
version of benchmarks/bench_uncertainty_coverage.py; tests/coverage_campaigns.py): one rig per
campaign drawn from its stated uncertainties, shared by its drops (J per fixture, the clock),
the extraction on the nominal rig. The 95 % intervals of the route's K' and loss factor hold the
truth in 95 % ± 2.5 % of 400 campaigns; the fit's intervals alone miss K' almost always (J's 1 %
does not average out over the drops) and the loss factor often (the clock)."""
import pytest

from coverage_campaigns import coverage


@pytest.mark.slow  # 400 campaigns of 6 drops (~5 s idle)
def test_the_route_intervals_cover_the_truth_and_the_fits_alone_under_cover():
    """One test for the shares of one set of 400 campaigns: tests that shared them through a
    cache ran them once per xdist worker when the workers split the module."""
    shares = coverage(400, seed=20261128)
    # binomial standard deviation over 400 campaigns: 1.1 %
    for name in ("k", "eta"):
        assert shares[name] == pytest.approx(0.95, abs=0.025), name
    assert shares["k_fit"] < 0.2
    assert shares["eta_fit"] < 0.8
