"""Model.load, predict and indices against the `predict` command on the same model,
calibration, designs and excitation (equal tables, bit for bit; each row on its own
excitation, as `--profile-id`), the flags and verdicts of a calibrated answer with their types
(Booleans, nulls, units), the refusals in the package's words (a model of another system,
another model's calibration, a missing or bad excitation), and Pipeline.status / show /
workspace."""

from __future__ import annotations

import json
import os
import subprocess

import numpy as np
import polars as pl
import pyarrow.parquet as pq
import pytest

import pino_mbd

from conftest import TINY
from test_system import assert_bit_identical


@pytest.fixture(scope="session")
def model_dir(run):
    return run.dir("train[algorithm=5]", "model.safetensors")


@pytest.fixture(scope="session")
def calibration(run):
    return run.dir("calibrate", "calibration.json").parent


@pytest.fixture(scope="session")
def model(model_dir, calibration):
    return pino_mbd.Model.load(model_dir, calibration=calibration)


def cli_predict(run, model_dir, calibration, tmp_path, *args, excitation=("--seed", "7")):
    out, ix = tmp_path / "out.parquet", tmp_path / "indices.parquet"
    cmd = [str(run.bins / "predict"), "--model", str(model_dir), "--calibration", str(calibration),
           *excitation, "--out", str(out), "--indices", str(ix), *args]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return pl.read_parquet(out), pl.read_parquet(ix)


def test_predict_and_indices_equal_the_cli(run, model, model_dir, calibration, tmp_path) -> None:
    # The second design is outside the training range of k_s (flagged by both).
    out, ix = cli_predict(run, model_dir, calibration, tmp_path, "--params", str(write_sets(tmp_path)))
    designs = pl.DataFrame({"k_s": [2.0e4, 4.0e4], "v_kmh": [60.0, 72.0]})
    with pytest.warns(UserWarning, match="outside the model's training ranges"):
        p = model.predict(designs, excitation=7)
    assert_bit_identical(p, out)
    with pytest.warns(UserWarning):
        i = model.indices(designs, excitation=7)
    assert_bit_identical(i, ix)
    assert i["outside_training_range"].to_list()[0] is None
    assert i["outside_training_range"].to_list()[1].startswith("k_s=")
    assert p.filter(pl.col("set") == 0)["outside_training_range"].null_count() == p.height // 2
    assert set(i["verdict"]) <= {"pass", "uncertain", "fail"}
    assert i["extrapolated"].to_list() == [False, True]
    assert i.schema["pass"] == pl.Boolean and i.schema["extrapolated"] == pl.Boolean
    lo, hi, v = i["suspension_travel_lo"], i["suspension_travel_hi"], i["suspension_travel"]
    assert ((lo <= v) & (v <= hi)).all()
    # One design by itself gives the same row as in the batch.
    one = model.indices({"k_s": 2.0e4, "v_kmh": 60.0}, excitation=7)
    assert_bit_identical(one.drop("set"), i.head(1).drop("set"))


def write_sets(tmp_path):
    p = tmp_path / "sets.yaml"
    p.write_text("- {k_s: 2.0e+4, v_kmh: 60.0}\n- {k_s: 4.0e+4, v_kmh: 72.0}\n")
    return p


def test_strict_refuses_designs_outside_the_training_ranges(model) -> None:
    with pytest.raises(ValueError, match=r"designs\[0\].*k_s="):
        model.indices({"k_s": [4.0e4]}, excitation=7, strict=True)


def test_a_model_of_another_system_and_another_calibration_are_refused(run, model_dir, model) -> None:
    # Designs of the vehicle-track model (its parameters) on the quarter car's model.
    with pytest.raises(ValueError, match=r"unknown parameter `k_pz`"):
        model.predict({"k_pz": [1.0e6]}, excitation=7)
    other = run.dir("calibrate", "calibration.json").parent / "algorithm-1" / "calibration.json"
    with pytest.raises(ValueError, match="calibration"):
        pino_mbd.Model.load(model_dir, calibration=other)
    with pytest.raises(ValueError, match="excitation"):
        model.predict({"k_s": [2.0e4]}, excitation=-1)
    with pytest.raises(ValueError):
        pino_mbd.Model.load(run.ws / "no-such-model")


def test_pipeline_status_and_show(run) -> None:
    st = run.pipeline.status()
    assert st.columns == ["unit", "state", "detail"]
    fresh = dict(st.select("unit", "state").iter_rows())
    assert fresh["calibrate"] == "fresh" and fresh["simulate#0"] == "fresh"
    assert fresh["evaluate"] == "never run"
    sims = run.pipeline.show("simulate")
    assert sum(p.endswith("/simulation.parquet") for p in sims) == 2
    with pytest.raises(ValueError, match="no_such_stage"):
        run.pipeline.show("no_such_stage")


def test_each_row_runs_on_its_own_excitation(run, model, model_dir, calibration, tmp_path) -> None:
    """Two rows of one design on excitations 1 and 0 (their `sample_id`): their own answers,
    each the CLI's with `--profile-id` that id; generated (a seed, its mapping) and from the
    profile table (a file or a DataFrame) alike."""
    sets = tmp_path / "one.yaml"
    sets.write_text("- {k_s: 2.0e+4, v_kmh: 60.0}\n")
    designs = pl.DataFrame({"sample_id": [1, 0], "k_s": [2.0e4] * 2, "v_kmh": [60.0] * 2})
    irregularity = run.files("irregularity", "irregularity.parquet")[0]
    profiles = json.loads((irregularity.parent / "profiles.json").read_text())
    for excitation, flag in [
        (7, ("--seed", "7")),
        ({"seed": 7, "dx": profiles["dx"]}, ("--seed", "7")),
        (irregularity, ("--profile", str(irregularity))),
        (pl.read_parquet(irregularity), ("--profile", str(irregularity))),
    ]:
        i = model.indices(designs, excitation=excitation)
        p = model.predict(designs, excitation=excitation)
        assert i.drop("set").row(0) != i.drop("set").row(1), excitation
        for row, id in enumerate([1, 0]):
            out, ix = cli_predict(run, model_dir, calibration, tmp_path, "--params", str(sets), "--profile-id", str(id), excitation=flag)
            assert_bit_identical(i.filter(pl.col("set") == row).drop("set"), ix.drop("set"))
            assert_bit_identical(p.filter(pl.col("set") == row).drop("set"), out.drop("set"))
    # Without `sample_id`, every row on `excitation_id` (default 0); the two disagreeing are
    # refused.
    same = model.indices(designs.drop("sample_id"), excitation=7)
    assert same.drop("set").row(0) == same.drop("set").row(1)
    assert_bit_identical(same, model.indices(designs.drop("sample_id"), excitation=7, excitation_id=0))
    with pytest.raises(pino_mbd.PinoError, match=r"excitation_id = 1, but designs\.sample_id\[1\] = 0: the `sample_id` column names"):
        model.indices(designs, excitation=7, excitation_id=1)
    # Rows of params.parquet (`split` ignored): each on the stream of its sample.
    params = pl.read_parquet(run.files("sample-params", "params.parquet")).head(3)
    rows = model.indices(params, excitation=profiles["seed"])
    for k, sid in enumerate(params["sample_id"]):
        one = model.indices(params[k].drop("sample_id", "split"), excitation=profiles["seed"], excitation_id=sid)
        assert_bit_identical(rows[k].drop("set"), one.drop("set"))


def test_refusals_speak_of_the_packages_arguments(model, quarter_car) -> None:
    """A missing or malformed excitation names the argument, never a CLI flag (the overrides'
    refusals: test_system)."""
    d = {"k_s": [2.0e4]}
    run = dict(duration=0.1, dt=2.0e-4, output_every=10, x0=5.0, progress=False)
    cases = [
        (lambda: model.indices(d), r"^excitation: missing; the system `quarter-car` has generated profile\(s\) road: give a seed"),
        (lambda: model.indices(d, excitation=1.5), r"^excitation = 1\.5: allowed a seed .*\{\"seed\": N, \"dx\": m, \"length\": m\}"),
        (lambda: model.indices(d, excitation=True), r"^excitation = True: allowed"),
        (lambda: model.indices(d, excitation={"seed": -1}), r"^excitation: seed -1: allowed an integer >= 0"),
        (lambda: model.indices(d, excitation={"seed": 7, "length": 50.0}), r"^excitation: range of `wavelengths`"),
        (lambda: quarter_car.simulate(d, excitation={"seed": 1, "length": 50.0}, **run), r"^excitation: range of `wavelengths`"),
        (lambda: quarter_car.simulate(d, excitation=[1, 2], **run), r"^excitation = \[1, 2\]: allowed a seed"),
    ]
    for call, pattern in cases:
        with pytest.raises(pino_mbd.PinoError, match=pattern) as e:
            call()
        text = str(e.value)
        assert "--" not in text and "sets[" not in text, text


def test_tables_have_booleans_nulls_and_one_dimensionless_unit(run, model) -> None:
    """`pass`, `extrapolated` are Booleans, an absent flag is null, and every dimensionless
    column is in `1`: in the package's tables and in the files the stages write."""
    native = model._native._answer("indices", pl.DataFrame({"k_s": [2.0e4, 4.0e4]}), 7, None, None, None, 16, False)
    units = dict(native.units)
    assert units["pass"] == units["extrapolated"] == units["set"] == units["outside_training_range"] == "1"
    assert "-" not in units.values(), units
    i = pl.DataFrame(native)
    assert i.schema["pass"] == pl.Boolean and i.schema["extrapolated"] == pl.Boolean
    assert i["outside_training_range"][0] is None
    indices = pq.read_schema(run.files("indices", "indices.parquet")[0])
    assert str(indices.field("pass").type) == "bool" and not indices.field("pass").nullable
    assert indices.field("failed").nullable
    assert all(f.metadata[b"unit"] != b"-" for f in indices), indices
    columns = pino_mbd.System.load(run.ws / "systems" / "quarter-car.yaml").columns
    assert dict(columns.select("name", "unit").iter_rows())["sample_id"] == "1"


def test_a_pipeline_runs_in_its_files_workspace_from_anywhere(run, tmp_path) -> None:
    """`Pipeline(path)` without a workspace: the file's directory, from any current
    directory; `show` of a stage never run names the workspace it looked in."""
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        p = pino_mbd.Pipeline(run.ws / "pipeline.yaml", set=TINY)
        assert p.workspace == str(run.ws)
        assert p.show("calibrate") == run.pipeline.show("calibrate")
        with pytest.raises(pino_mbd.PinoError, match=f"no outputs yet in the workspace {run.ws}: `pipeline -C {run.ws} -f pipeline.yaml run evaluate`"):
            p.show("evaluate")
    finally:
        os.chdir(here)
    assert not (tmp_path / "artifacts").exists()


def test_export_onnx_writes_the_export_commands_file(run, model, model_dir, calibration, tmp_path) -> None:
    import onnxruntime as ort

    mine, cli = tmp_path / "model.onnx", tmp_path / "cli.onnx"
    assert "indices" in model.export_onnx(mine)
    cmd = [str(run.bins / "export"), "--model", str(model_dir), "--calibration", str(calibration),
           "--out", str(cli)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert mine.read_bytes() == cli.read_bytes()
    meta = ort.InferenceSession(str(mine)).get_modelmeta().custom_metadata_map
    assert json.loads(meta["pino.surrogate"])["system"]["name"] == model.system_name
    with pytest.raises(ValueError, match="level 0.9999"):
        model.export_onnx(tmp_path / "refused.onnx", levels=[0.9999])
    assert not (tmp_path / "refused.onnx").exists()
