"""The package on the vehicle in space: the surrogate of configs/vtcd-3d.yaml's job (at small
sizes) answers the lateral indices (Y/Q, the wheelset lateral force, lateral ride, stability)
with their intervals, one track per row or one for all, and its tables equal
`predict --surrogate` bit for bit."""

from __future__ import annotations

import polars as pl
import pytest

import pino_mbd

from test_system import assert_bit_identical

LATERAL = ["derailment_quotient_2m", "wheelset_lateral_force_kn", "sperling_wy_centre",
           "lateral_stability_growth_1ps"]


@pytest.fixture(scope="session")
def surrogate_3d(run_3d) -> tuple[pino_mbd.Surrogate, object]:
    d = run_3d.dir("surrogate", "surrogate.json")
    return pino_mbd.Surrogate.load(d), d


def test_the_vehicle_in_space_answers_its_lateral_indices_as_the_command(run_3d, surrogate_3d, tmp_path) -> None:
    surrogate, d = surrogate_3d
    assert surrogate.system_name == "vehicle-track-3d" and surrogate.calibrated
    designs = pl.DataFrame({"gamma": [0.15, 0.3], "c_yaw": [3.0e5, 1.5e5]})
    out, ix = run_3d.predict(d, designs, tmp_path)
    indices = surrogate.indices(designs, excitation=7)
    for name in LATERAL:
        assert {name, f"{name}_lo", f"{name}_hi"} <= set(indices.columns), name
        assert (indices[f"{name}_lo"] <= indices[name]).all() and (indices[name] <= indices[f"{name}_hi"]).all()
    assert indices["derailment_quotient_2m"].is_finite().all()
    assert_bit_identical(indices, ix)
    assert_bit_identical(surrogate.predict(designs, excitation=7), out)
    # One track per row: stream 0 is the common track above, stream 8 another.
    per_row = surrogate.indices(designs.with_columns(pl.Series("sample_id", [0, 8])), excitation=7)
    assert_bit_identical(per_row.select(indices.columns).head(1), indices.head(1))
    assert per_row["derailment_quotient_2m"][1] != indices["derailment_quotient_2m"][1]
