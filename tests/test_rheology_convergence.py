"""Time-step convergence of every shipped preset at the two sample rates the project uses:
38.4 kHz (the drop tower's amplifier, the rig's step) and 2048 Hz (the servo bench)."""
from __future__ import annotations

import numpy as np
import pytest

from droptower.rheology import load_coupling
from test_rheology_support import preset_paths, preset_scale, random_smooth

#: max |T(h) - T(h/2)| / max |T| every preset must meet at each rate (a preset calibrated anew
#: included). The updates are exact (Maxwell, Pfeffer, Coulomb sliders, springs) or backward
#: Euler (rate-dependent sliders, variable Maxwell; the ``payne`` element reads each half
#: cycle's amplitude at the steps, docs/theory.md#payne): first order, so the change on halving
#: is about half the error at h, and it grows in proportion to h. Each preset's own figures are
#: stored (tests/data/regression/test_rheology_convergence.json, ``python tests/regenerate.py``).
TOLERANCE = {38400.0: 1e-3, 2048.0: 1e-2}
#: The stored figures' reproducibility: the histories are deterministic up to the kernels'
#: round-off (summation order, ~1e-15 of the torque per step), which moves a change of >= 1e-6
#: by far less than 1e-6 of itself; an exact preset's change is round-off itself, hence the
#: absolute part.
REPRODUCIBLE = dict(rel=1e-6, atol=1e-10)


def _change_on_halving(coupling, rate_hz):
    """Relative change of the torque history at the common samples when the step halves.

    History: three periods of the preset's representative frequency, a sine (0.7 of its
    amplitude) plus a band-limited random part (the zero-dimensional model paper's random profile; 0.6 of it; fixed
    seed), both evaluated in closed form at every sample of either rate."""
    amplitude, frequency = preset_scale(coupling)
    n = int(round(3.0 / frequency * rate_hz))
    torques = []
    for m in (1, 2):
        t = np.arange(1, m * n + 1) / (m * rate_hz)
        x = amplitude * (0.7 * np.sin(2 * np.pi * frequency * t)
                         + 0.6 * random_smooth(np.random.default_rng(2022), t, frequency))
        torques.append(coupling.respond(x, 1.0 / (m * rate_hz)))
    coarse, fine = torques[0], torques[1][1::2]
    return np.max(np.abs(coarse - fine)) / np.max(np.abs(torques[1]))


@pytest.mark.parametrize("path", preset_paths(), ids=lambda p: p.stem)
def test_halving_the_step_changes_little(path, regression):
    coupling = load_coupling(path)
    changes = {rate: _change_on_halving(coupling, rate) for rate in TOLERANCE}
    for rate, change in changes.items():
        assert change < TOLERANCE[rate], f"{rate:.0f} Hz: {change:.2e}"
        regression.check(f"change_on_halving_at_{rate:.0f}_hz", change, **REPRODUCIBLE)
    # consistent: the change shrinks at least linearly with the step (38400/2048 = 18.75;
    # >= 8 leaves room for round-off-level changes of the exact kernels)
    assert changes[2048.0] > 8 * changes[38400.0] or changes[2048.0] < 1e-9
