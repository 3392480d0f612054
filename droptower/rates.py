"""The package's two default sample rates, named once.

- :data:`RIG_SAMPLE_RATE_HZ`: the drop tower's data acquisition (the amplifier samples up to
  38 kHz, Rapp et al. 2022, docs/theory.md#rig); the rig's default output rate, the step of
  the compiled lever and of the FMU, and the servo bench's default simulation rate;
- :data:`SERVO_SAMPLE_RATE_HZ`: the servo-hydraulic comparison bench's acquisition rate
  (Rapp et al. 2022, docs/theory.md#rig); the default rate of servo records.

A module of its own (no imports) so that the servo bench, the FMU, the synthetic logs and the
identification name the rig's rate without importing the rig (pymunk) against the data flow.
``tests/test_rates.py`` checks that the figures the documentation quotes are these.
"""
from __future__ import annotations

__all__ = ["RIG_SAMPLE_RATE_HZ", "SERVO_SAMPLE_RATE_HZ"]

#: Hz: the drop tower's sample rate (Rapp et al. 2022)
RIG_SAMPLE_RATE_HZ = 38_400.0
#: Hz: the servo bench's sample rate (Rapp et al. 2022)
SERVO_SAMPLE_RATE_HZ = 2_048.0
