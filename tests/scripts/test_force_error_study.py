"""scripts/force-error-study.py on the tiny quarter-car run: its band split is exact at the
ends of the spectrum (all of the error taken out leaves none; none taken out leaves the model's
own) and the ensemble of two models bounds its extremes by theirs."""

from __future__ import annotations

import pytest

from conftest import script as load_script


@pytest.fixture(scope="module")
def script():
    return load_script("force-error-study.py")


def test_band_split_and_ensemble(run, script):
    stage, other = "train[algorithm=5]", "train[algorithm=1]"
    # cut 0 Hz: "at or above" is every line of the error spectrum, "below" none.
    got = script.study(run.pipeline, [stage, other], "validation", cut_hz=0.0, lags=2)
    m = got[stage]
    assert m["samples"] == 4
    assert m["reduction_error_pct"] > 0.0
    assert m["above_cut_removed_pct"] == pytest.approx(0.0, abs=1e-9)
    assert m["below_cut_removed_pct"] == pytest.approx(m["reduction_error_pct"], rel=1e-9)
    # The ensemble is the mean of the two predictions: its highest force is at most the mean of
    # theirs and its lowest at least (per sample, against the same solver), so its signed peak
    # error lies at or below the members' mean and its deepest-unloading error at or above.
    mean = got["mean of all"]
    members = [got[s] for s in (stage, other)]
    assert members[0]["peak_error_kn"] != members[1]["peak_error_kn"]
    assert mean["peak_error_kn"] <= sum(x["peak_error_kn"] for x in members) / 2 + 1e-12
    low = sum(x["deepest_unloading_error_kn"] for x in members) / 2
    assert mean["deepest_unloading_error_kn"] >= low - 1e-12
    assert all(mean["peak_error_kn"] != x["peak_error_kn"] for x in members)
    assert m["filter_variance_share_pct"] < 100.0
