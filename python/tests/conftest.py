"""A tiny real pipeline run of the quarter car (configs/quarter-car.yaml with small sizes),
and one of the vehicle in space (configs/vtcd-3d.yaml) for the tests that need it, each made
once per session through ``pino_mbd.Pipeline`` with the workspace's stage binaries
(``PINO_BIN_DIR``, else ``target/debug``: ``scripts/test`` builds them first). The tests compare
the package's answers with the files those stages and the ``predict`` command write.

The quarter car's workspace is ``PINO_TEST_WORKSPACE`` when set (``scripts/test`` sets it, so that the
research scripts' tests, tests/scripts, find the same run done and run nothing again), else a
temporary directory of the session."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import polars as pl
import pytest

import pino_mbd

ROOT = Path(__file__).resolve().parents[2]

# Small sizes: seconds of data and training, enough samples for a calibration at 0.9.
TINY = {
    "sample-params.n_train": 4,
    "sample-params.n_validation": 4,
    "sample-params.n_test": 1,
    "sample-params.n_calibration": 12,
    "simulate.duration": 0.5,
    "train.epochs": 2,
    "train.width": 8,
    "train.modes": 8,
    "train.projection_width": 16,
    "train.batch_size": 2,
    # Two epochs of a width-8 network: the file's 3e-3 is chosen for 20 epochs of the real one.
    "train.learning_rate": 1.0e-3,
}


def bin_dir() -> Path:
    d = Path(os.environ.get("PINO_BIN_DIR") or ROOT / "target" / "debug")
    for exe in ("pipeline", "sample-params", "irregularity", "simulate", "train", "calibrate", "predict"):
        if not (d / exe).is_file():
            raise RuntimeError(
                f"{d / exe} is missing: build the stages first (`cargo build --workspace --bins`, as scripts/test does) or set PINO_BIN_DIR"
            )
    return d


class Run:
    """The pipeline run and where its outputs are."""

    def __init__(self, ws: Path, bins: Path, sets: dict = TINY) -> None:
        self.ws = ws
        self.bins = bins
        self.pipeline = pino_mbd.Pipeline("pipeline.yaml", workspace=ws, set=sets)

    def dir(self, stage: str, file: str) -> Path:
        return Path(self.pipeline.dir(stage, file))

    def files(self, stage: str, file: str) -> list[Path]:
        return [Path(p) for p in self.pipeline.show(stage) if os.path.basename(p) == file]

    def predict(self, surrogate: Path, designs: pl.DataFrame, tmp: Path) -> tuple[pl.DataFrame, pl.DataFrame]:
        """The ``predict --surrogate --seed 7`` command's tables of ``designs`` (one design per
        row, every column a parameter): the channels (``--out``) and the indices (``--indices``)."""
        sets, out, ix = tmp / "sets.yaml", tmp / "out.parquet", tmp / "indices.parquet"
        sets.write_text("".join(
            "- {" + ", ".join(f"{k}: {v!r}" for k, v in row.items()) + "}\n"
            for row in designs.iter_rows(named=True)))
        cmd = [str(self.bins / "predict"), "--surrogate", str(surrogate), "--seed", "7",
               "--params", str(sets), "--out", str(out), "--indices", str(ix)]
        r = subprocess.run(cmd, capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        return pl.read_parquet(out), pl.read_parquet(ix)


def workspace(ws: Path, bins: Path, job: str) -> None:
    """Makes ``ws`` a workspace of the job ``configs/<job>`` unless it is one already."""
    if (ws / "pipeline.yaml").is_file():
        return
    # The pipeline file's bin_dir must lie inside the workspace: links to the binaries
    # there; the file is the workspace's own (its `workspace: ..` dropped). It is written
    # last: a workspace with the file is a finished setup.
    ws.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(ws / "systems", ignore_errors=True)
    shutil.copytree(ROOT / "systems", ws / "systems")
    shutil.rmtree(ws / "bin", ignore_errors=True)
    (ws / "bin").mkdir()
    for exe in bins.iterdir():
        if exe.is_file() and os.access(exe, os.X_OK) and not exe.suffix:
            (ws / "bin" / exe.name).symlink_to(exe)
    text = (ROOT / "configs" / job).read_text()
    text = re.sub(r"(?m)^workspace: .*\n", "", re.sub(r"(?m)^bin_dir: .*$", "bin_dir: bin", text))
    (ws / "pipeline.yaml").write_text(text)


@pytest.fixture(scope="session")
def run(tmp_path_factory: pytest.TempPathFactory) -> Run:
    bins = bin_dir()
    shared = os.environ.get("PINO_TEST_WORKSPACE")
    ws = Path(shared) if shared else tmp_path_factory.mktemp("ws")
    workspace(ws, bins, "quarter-car.yaml")
    r = Run(ws, bins)
    r.pipeline.run(["calibrate", "indices"], jobs=2)
    return r


# The vehicle in space's job at small sizes: runs of 1 s from 200 m, so that every record ends
# with the stability index's 0.5 s of ideal track (the irregularities end at 230 m).
TINY_3D = {**TINY, "simulate.duration": 1.0, "simulate.x0": 200.0}


@pytest.fixture(scope="session")
def run_3d(tmp_path_factory: pytest.TempPathFactory) -> Run:
    """The vehicle in space's job (configs/vtcd-3d.yaml) at TINY_3D sizes, up to its
    surrogate."""
    bins = bin_dir()
    ws = tmp_path_factory.mktemp("ws3d")
    workspace(ws, bins, "vtcd-3d.yaml")
    r = Run(ws, bins, TINY_3D)
    r.pipeline.run(["surrogate"], jobs=2)
    return r


@pytest.fixture(scope="session")
def quarter_car() -> pino_mbd.System:
    return pino_mbd.System.load(ROOT / "systems" / "quarter-car.yaml")
