"""Rounded time stamps: a constant rate printed with few decimals or significant digits is
recovered exactly from the whole record; time bases that rounding cannot explain are refused."""
from __future__ import annotations

import numpy as np
import pytest

from droptower.errors import DroptowerError
from droptower.io.timebase import printed_precision, regular_time


def _printed(values: np.ndarray, fmt: str) -> np.ndarray:
    """Stamps as a lab export prints them and a reader parses them back."""
    return np.array([float(fmt % v) for v in values])


@pytest.mark.parametrize("draw", range(12))
def test_random_rates_and_precisions_come_back_exactly(draw):
    rng = np.random.default_rng(draw)
    rate = float(rng.choice([100, 500, 512, 1000, 1024, 2000, 2048, 4096, 5000]))
    n = int(rng.integers(200, 20000))
    start = float(rng.choice([0.0, -0.1, 3.25]))
    exact = start + np.arange(n) / rate
    decimals = int(rng.integers(np.ceil(np.log10(rate)) , 7))  # a digit at most a step, as labs print
    stamps = _printed(exact, f"%.{decimals}f")
    if np.all(np.diff(stamps) > 0):
        uniform, note = regular_time(stamps)
        assert (uniform.size - 1) / (uniform[-1] - uniform[0]) == pytest.approx(rate, rel=1e-12)
        np.testing.assert_allclose(uniform, exact, rtol=0, atol=1e-12 * max(1.0, abs(exact).max()))
        if note is not None:
            assert f"constant {rate:g} Hz" in note


def test_significant_digits_and_a_rate_of_no_whole_hertz():
    """7 significant digits (the issue's export: 0.0009765625 .. 19.99902) and 1/0.0003 s."""
    exact = np.arange(20 * 1024) / 1024.0
    uniform, note = regular_time(_printed(exact, "%.7g"))
    np.testing.assert_allclose(uniform, exact, rtol=0, atol=1e-12)
    assert "printed to 7 significant digits" in note
    exact = 2.0 + np.arange(5000) * 0.0003
    uniform, note = regular_time(np.round(exact, 4))
    assert (uniform[-1] - uniform[0]) / (uniform.size - 1) == pytest.approx(0.0003, rel=1e-9)
    assert printed_precision(np.round(exact, 4))[0][0] == "4 decimals"


def test_stamps_stored_as_float32():
    """10 s at 20 kHz in float32: steps off by up to 2 % of a step, a rounding all the same."""
    exact = np.arange(200_000) / 20_000.0
    stamps = exact.astype(np.float32).astype(np.float64)
    uniform, note = regular_time(stamps)
    np.testing.assert_allclose(uniform, exact, rtol=0, atol=1e-12)
    assert "float32 precision" in note and "constant 20000 Hz" in note


@pytest.mark.parametrize("draw", range(6))
def test_jitter_beyond_the_printed_precision_is_refused(draw):
    rng = np.random.default_rng(100 + draw)
    exact = np.arange(2000) / 1024.0
    jittered = exact + rng.normal(0.0, 3e-5, exact.size)  # 3 % of a step, printed to 6 decimals
    stamps = np.round(jittered, 6)
    with pytest.raises(DroptowerError, match=r"log\.csv: time: the time step is not constant .* more than rounding"):
        regular_time(stamps, file="log.csv", where="time")


def test_a_missing_sample_is_refused():
    exact = np.delete(np.arange(1000) / 512.0, 400)
    with pytest.raises(DroptowerError, match="the time step is not constant"):
        regular_time(np.round(exact, 4))


def test_exact_stamps_pass_unchanged():
    t = np.arange(100) / 300.0
    uniform, note = regular_time(t)
    assert uniform is t and note is None
