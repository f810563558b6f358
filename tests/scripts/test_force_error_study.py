"""scripts/force-error-study.py on the tiny quarter-car run: its band split is exact at the
ends of the spectrum (all of the error taken out leaves none; none taken out leaves the model's
own) and the ensemble of one model twice is that model."""

from __future__ import annotations

import pytest

from conftest import script as load_script


@pytest.fixture(scope="module")
def script():
    return load_script("force-error-study.py")


def test_band_split_and_ensemble(run, script):
    stage = "train[algorithm=5]"
    # cut 0 Hz: "at or above" is every line of the error spectrum, "below" none.
    got = script.study(run.pipeline, [stage, stage], "validation", cut_hz=0.0, lags=2)
    m = got[stage]
    assert m["samples"] == 4
    assert m["reduction_error_pct"] > 0.0
    assert m["above_cut_removed_pct"] == pytest.approx(0.0, abs=1e-9)
    assert m["below_cut_removed_pct"] == pytest.approx(m["reduction_error_pct"], rel=1e-9)
    # The mean of a model and itself is the model.
    assert got["mean of all"]["reduction_error_pct"] == pytest.approx(m["reduction_error_pct"], rel=1e-12)
    assert m["filter_variance_share_pct"] < 100.0
