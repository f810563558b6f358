"""System.load and System.simulate: the description's tables, its errors with file:line, the
solver's output equal to the `simulate` stage's file bit for bit, the GIL released during the
run, and bad designs refused with ValueError naming the field."""

from __future__ import annotations

import json
import re
import threading
import time

import numpy as np
import pandas as pd
import polars as pl
import pytest

import pino_mbd
from conftest import ROOT


def test_the_quarter_car_is_described_with_units(quarter_car: pino_mbd.System) -> None:
    p = quarter_car.parameters
    m_s = p.filter(pl.col("name") == "m_s").row(0, named=True)
    assert (m_s["unit"], m_s["kind"], m_s["nominal"]) == ("kg", "sampled", 320.0)
    assert (m_s["min"], m_s["max"]) == pytest.approx((256.0, 384.0))
    g = p.filter(pl.col("name") == "g").row(0, named=True)
    assert (g["kind"], g["nominal"], g["min"]) == ("fixed", 9.81, None)
    assert quarter_car.design_parameters == ["m_s", "m_u", "k_s", "c_s", "k_t", "v_kmh"]
    cols = dict(quarter_car.columns.select("name", "unit").iter_rows())
    assert cols["t"] == "s" and cols["z_s"] == "m" and cols["z_s_a"] == "m/s^2" and cols["f_tyre"] == "N"
    ix = quarter_car.indices.filter(pl.col("name") == "suspension_travel").row(0, named=True)
    assert (ix["unit"], ix["limit"]) == ("m", 0.08)
    # The quarter car's indices read the whole record; the vehicle track's from 0.2 s.
    assert quarter_car.indices_from == 0.0
    assert pino_mbd.System.load(ROOT / "systems" / "vtcd.yaml").indices_from == 0.2


def test_a_bad_description_raises_with_file_and_line(tmp_path) -> None:
    bad = tmp_path / "bad.yaml"
    src = (
        "format: 1\nname: bad\nparameters:\n  m: {unit: kg, nominal: 2, range: [1, 3]}\n"
        "bodies:\n  b: {mass: m, dofs: [z]}\n"
        "elements:\n  spring: {kind: spring_damper, from: b, to: nowhere, k: 1.0}\n"
    )
    bad.write_text(src)
    with pytest.raises(ValueError, match=r"bad\.yaml:8") as e:
        pino_mbd.System.load(bad)
    assert "nowhere" in str(e.value)
    assert isinstance(e.value, pino_mbd.PinoError)


def test_values_override_the_description(quarter_car) -> None:
    s = pino_mbd.System.load(quarter_car.path, values={"g": 9.0, "k_s": [1.0e4, 3.0e4]})
    row = s.parameters.filter(pl.col("name") == "k_s").row(0, named=True)
    assert (row["min"], row["max"]) == (1.0e4, 3.0e4)
    assert s.hash != quarter_car.hash
    with pytest.raises(ValueError, match="no_such"):
        pino_mbd.System.load(quarter_car.path, values={"no_such": 1.0})
    # In the argument's words: not the stages' `system_values`, not a line of the file.
    for values, pattern in [
        ({"k_q": 1}, r"^values\.k_q: `k_q` is not a parameter of the description; parameters: "),
        ({"g": [1.0, 2.0]}, r"^values\.g: a fixed parameter takes a finite number"),
    ]:
        with pytest.raises(pino_mbd.PinoError, match=pattern) as e:
            pino_mbd.System.load(quarter_car.path, values=values)
        assert "system_values" not in str(e.value) and ":1:1" not in str(e.value), e.value


def stage_inputs(run):
    params = pl.read_parquet(run.files("sample-params", "params.parquet"))
    irregularity = run.files("irregularity", "irregularity.parquet")[0]
    sims = run.files("simulate", "simulation.parquet")
    controls = json.loads((sims[0].parent / "run.json").read_text())["run"]
    reference = pl.concat([pl.read_parquet(f) for f in sims]).sort("sample_id", "t", maintain_order=True)
    return params, irregularity, controls, reference


def bits(df: pl.DataFrame) -> dict[str, np.ndarray]:
    return {c: df[c].to_numpy().view(np.int64) if df[c].dtype == pl.Float64 else df[c].to_numpy() for c in df.columns}


def assert_bit_identical(a: pl.DataFrame, b: pl.DataFrame) -> None:
    assert a.columns == b.columns
    assert a.schema == b.schema
    ba, bb = bits(a), bits(b)
    for c in a.columns:
        assert np.array_equal(ba[c], bb[c]), c


def test_simulate_gives_the_stage_file_bit_for_bit(run, quarter_car) -> None:
    params, irregularity, c, reference = stage_inputs(run)
    kw = {k: c[k] for k in ("duration", "dt", "output_every", "start", "x0", "startup_zero_fraction", "startup_ramp_fraction")}
    sim = quarter_car.simulate(params, excitation=irregularity, progress=False, **kw)
    assert sim.height == reference.height > 0
    assert_bit_identical(sim, reference)
    # The same designs as pandas, with the profiles generated as `irregularity` does.
    prof = json.loads((irregularity.parent / "profiles.json").read_text())
    gen = {k: prof[k] for k in ("seed", "dx", "length")}
    sim2 = quarter_car.simulate(params.to_pandas(), excitation=gen, progress=False, **kw)
    assert_bit_identical(sim2, reference)
    assert isinstance(sim2.to_pandas(), pd.DataFrame)


def test_simulate_releases_the_gil(quarter_car) -> None:
    n = 400
    designs = {"k_s": np.linspace(2.0e4, 2.4e4, n), "sample_id": np.arange(n)}
    ticks: list[float] = []
    stop = threading.Event()

    def tick() -> None:
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.0005)

    t = threading.Thread(target=tick)
    t.start()
    try:
        time.sleep(0.01)
        t0 = time.perf_counter()
        sim = quarter_car.simulate(
            designs, excitation={"seed": 3, "dx": 0.1, "length": 200.0},
            duration=2.0, dt=2.0e-4, output_every=10, x0=5.0, progress=False,
        )
        t1 = time.perf_counter()
    finally:
        stop.set()
        t.join()
    assert sim["sample_id"].n_unique() == n
    during = [x for x in ticks if t0 < x < t1]
    # With the GIL held the thread could not run at all while the solver works.
    assert len(during) >= 3, (len(during), t1 - t0)


RUN = dict(duration=0.1, dt=2.0e-4, output_every=10, x0=5.0, progress=False, excitation={"seed": 1, "dx": 0.1, "length": 200.0})


@pytest.mark.parametrize(
    "designs, pattern",
    [
        ({"k_z": [1.0]}, r"unknown parameter `k_z`"),
        ({"g": [9.0]}, r"`g` is not sampled"),
        ({"k_s": [2.0e4, float("nan")]}, r"designs\.k_s\[1\] = NaN"),
        ({"k_s": [[2.0e4, 2.1e4]]}, r"designs\.k_s: a 1-D array"),
        ({"k_s": [2.0e4, 2.1e4], "c_s": [1500.0]}, r"different lengths.*k_s: 2, c_s: 1"),
        ({"m_s": [-1.0]}, r"designs\[0\]\.m_s"),
        ({"k_s": ["soft"]}, r"designs\.k_s: numbers"),
        ({"sample_id": [1, 1]}, r"designs\.sample_id: 1 appears twice"),
        ({"k_s": []}, r"designs: no rows"),
        ([1, 2], r"designs: expected a polars or pandas DataFrame"),
    ],
)
def test_bad_designs_raise_value_error_naming_the_field(quarter_car, designs, pattern) -> None:
    with pytest.raises(ValueError, match=pattern):
        quarter_car.simulate(designs, **RUN)


def test_bad_run_controls_and_excitations_are_named(quarter_car) -> None:
    d = {"k_s": [2.0e4]}
    with pytest.raises(ValueError, match="dt"):
        quarter_car.simulate(d, **{**RUN, "dt": -1.0})
    with pytest.raises(ValueError, match="start"):
        quarter_car.simulate(d, **{**RUN, "start": "sideways"})
    with pytest.raises(ValueError, match=r"^excitation: missing; the system `quarter-car` has generated profile\(s\) road"):
        quarter_car.simulate(d, **{**RUN, "excitation": None})
    with pytest.raises(ValueError, match="unknown key `sed`"):
        quarter_car.simulate(d, **{**RUN, "excitation": {"sed": 1, "dx": 0.1, "length": 200.0}})


def test_one_excitation_vocabulary_with_documented_defaults(run, quarter_car) -> None:
    """A seed is `{"seed": N}`; the solver's default spacing is 0.1 m and its default length
    covers the run over the sampling ranges (here the 90 m longest wavelength of the road);
    a profile table given as a DataFrame or a file is the same excitation, row by row."""
    d = {"k_s": [2.0e4, 2.4e4], "sample_id": [3, 5]}
    kw = dict(duration=0.2, dt=2.0e-4, output_every=10, x0=5.0, progress=False)
    seed = quarter_car.simulate(d, excitation=4, **kw)
    assert_bit_identical(seed, quarter_car.simulate(d, excitation={"seed": 4}, **kw))
    assert_bit_identical(seed, quarter_car.simulate(d, excitation={"seed": 4, "dx": 0.1, "length": 90.0}, **kw))
    assert not seed.filter(pl.col("sample_id") == 3)["eta_tyre"].equals(seed.filter(pl.col("sample_id") == 5)["eta_tyre"])
    # A run that reaches farther gets a longer road: 5 m + 30 m/s x 4 s, + dx, to 130 m.
    long = dict(kw, duration=4.0)
    assert_bit_identical(
        quarter_car.simulate({"k_s": [2.0e4]}, excitation=4, **long),
        quarter_car.simulate({"k_s": [2.0e4]}, excitation={"seed": 4, "dx": 0.1, "length": 130.0}, **long),
    )
    irregularity = run.files("irregularity", "irregularity.parquet")[0]
    params = pl.read_parquet(run.files("sample-params", "params.parquet")).head(2)
    from_file = quarter_car.simulate(params, excitation=irregularity, **kw)
    assert_bit_identical(from_file, quarter_car.simulate(params, excitation=pl.read_parquet(irregularity), **kw))
