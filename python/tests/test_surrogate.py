"""Surrogate.load on the tiny run's `surrogate` output (built from the fixtures' trained models
and their calibrations): every index, interval and verdict is the one its routed member gives
as a `Model`, every channel and band the routed member's, the tables equal `predict --surrogate`
bit for bit, and a changed member or a manifest of another system is refused with the
command's message."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import pino_mbd

from test_system import assert_bit_identical, bits

DESIGNS = pl.DataFrame({"sample_id": [1, 0], "k_s": [2.0e4, 2.5e4], "v_kmh": [60.0, 72.0]})


@pytest.fixture(scope="session")
def surrogate_dir(run) -> Path:
    run.pipeline.run("surrogate")
    return run.dir("surrogate", "surrogate.json")


@pytest.fixture(scope="session")
def surrogate(surrogate_dir) -> pino_mbd.Surrogate:
    return pino_mbd.Surrogate.load(surrogate_dir)


def member(surrogate_dir: Path, name: str) -> pino_mbd.Model:
    at = surrogate_dir / "members" / name
    return pino_mbd.Model.load(at, calibration=at / "calibration.json")


def same(a: pl.Series, b: pl.Series) -> bool:
    """Equal bit for bit (numbers) or value for value."""
    return a.dtype == b.dtype and np.array_equal(bits(a.to_frame())[a.name], bits(b.to_frame())[b.name])


def test_each_answer_is_its_routed_members(run, surrogate, surrogate_dir) -> None:
    manifest = json.loads((surrogate_dir / "surrogate.json").read_text())
    assert surrogate.members == [m["name"] for m in manifest["members"]]
    assert surrogate.index_routes == {r["name"]: r["member"] for r in manifest["indices"]}
    assert surrogate.system_name == "quarter-car" and surrogate.calibrated
    # The tiny run's candidates split the indices among several members (seeded: always so).
    assert len(set(surrogate.index_routes.values())) > 1, surrogate.index_routes
    models = {name: member(surrogate_dir, name) for name in surrogate.members}
    mine = surrogate.indices(DESIGNS, excitation=7)
    theirs = {name: m.indices(DESIGNS, excitation=7) for name, m in models.items()}
    assert mine.height == 2 and mine.drop("set").row(0) != mine.drop("set").row(1)
    for index, name in surrogate.index_routes.items():
        for col in (index, f"{index}_lo", f"{index}_hi", f"{index}_verdict"):
            if col in theirs[name].columns:
                assert same(mine[col], theirs[name][col]), (col, name)
    # The combined answers, judged on the assembled indices.
    assert mine["pass"].to_list() == mine["failed"].is_null().to_list()
    assert set(mine["verdict"]) <= {"pass", "uncertain", "fail"}
    histories = surrogate.predict(DESIGNS, excitation=7)
    own = {name: m.predict(DESIGNS, excitation=7) for name, m in models.items()}
    routed = [c for c in surrogate.channel_routes if f"{c}_lo" in histories.columns]
    assert routed, histories.columns
    for channel, name in surrogate.channel_routes.items():
        for col in (channel, f"{channel}_lo", f"{channel}_hi"):
            if col in histories.columns:
                assert same(histories[col], own[name][col]), (col, name)
    assert histories["outside_training_range"].null_count() == histories.height


def test_the_tables_are_the_commands(run, surrogate, surrogate_dir, tmp_path) -> None:
    designs = pl.DataFrame({"k_s": [2.0e4, 4.0e4], "v_kmh": [60.0, 72.0]})
    out, ix = run.predict(surrogate_dir, designs, tmp_path)
    with pytest.warns(UserWarning, match="outside"):
        assert_bit_identical(surrogate.predict(designs, excitation=7), out)
    with pytest.warns(UserWarning, match="outside"):
        assert_bit_identical(surrogate.indices(designs, excitation=7), ix)


def refusals(surrogate_dir: Path, tmp_path: Path):
    """Each broken copy of the surrogate: (what was broken, its directory)."""
    def copy(name: str) -> Path:
        d = tmp_path / name
        shutil.copytree(surrogate_dir, d)
        return d

    changed = copy("changed")
    name = json.loads((changed / "surrogate.json").read_text())["members"][0]["name"]
    weights = changed / "members" / name / "model.safetensors"
    data = bytearray(weights.read_bytes())
    data[-1] ^= 1
    weights.write_bytes(bytes(data))
    yield name, weights, changed
    foreign = copy("foreign")
    manifest = json.loads((foreign / "surrogate.json").read_text())
    manifest["system"] = "vtcd"
    (foreign / "surrogate.json").write_text(json.dumps(manifest))
    yield name, foreign / "surrogate.json", foreign


def test_a_changed_member_and_a_foreign_manifest_are_refused_as_the_command(run, surrogate_dir, tmp_path) -> None:
    sets = tmp_path / "sets.yaml"
    sets.write_text("- {k_s: 2.0e+4, v_kmh: 60.0}\n")
    for name, file, d in refusals(surrogate_dir, tmp_path):
        with pytest.raises(pino_mbd.PinoError) as e:
            pino_mbd.Surrogate.load(d)
        message = str(e.value)
        assert str(file) in message and f"member model `{name}`" in message, message
        assert "--" not in message, message
        cmd = [str(run.bins / "predict"), "--surrogate", str(d), "--seed", "7",
               "--params", str(sets), "--indices", str(tmp_path / "x.parquet")]
        r = subprocess.run(cmd, capture_output=True, text=True)
        assert r.returncode == 2 and message in r.stderr, (r.returncode, r.stderr)
    assert not (tmp_path / "x.parquet").exists()
