"""scripts/startup-transient.py on the quarter car: with no lead the two runs are one run (no
difference at all), and with a lead the start's trace in the wheel's acceleration dies away
(the first bin after the start holds the largest difference)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

import pino_mbd
from conftest import script as load_script


@pytest.fixture(scope="module")
def script():
    return load_script("startup-transient.py")


def controls(lead: float) -> argparse.Namespace:
    return argparse.Namespace(
        seed=1, duration=0.6, dt=2.0e-4, output_every=10, x0=5.0, lead=lead, speed="v_kmh / 3.6",
        start="equilibrium", excitation_dx=0.1, excitation_length=200.0,
    )


def test_no_lead_is_one_run_and_a_lead_decays(script, quarter_car: pino_mbd.System):
    system = quarter_car
    designs = script.designs(system, 3, seed=2)
    assert designs.height == 3 and set(system.design_parameters) <= set(designs.columns)
    same = script.differences(system, designs, controls(0.0))
    assert "z_u_a" in same and "eta_tyre" not in same
    assert all(float(d.max()) == 0.0 for d in same.values())
    diff = script.differences(system, designs, controls(1.0))
    wheel = diff["z_u_a"]  # designs x rows, relative to the column's spread
    first, last = wheel[:, :25].max(), wheel[:, -50:].max()
    assert first > 0.5 and last < 0.2 * first, (first, last)
    assert np.isfinite(wheel).all()
