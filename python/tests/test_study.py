"""The study function gives the study stage's results: the quarter car's Monte Carlo study
(`bump_stop` of configs/quarter-car.yaml, which reads the surrogate) run by the pipeline and by
`pino_mbd.study` with the same declaration and parameters, on the same surrogate, write equal
tables."""

from __future__ import annotations

import json
from pathlib import Path

import polars as pl

import pino_mbd

from test_system import assert_bit_identical

BUMP_STOP = {"name": "bump_stop", "kind": "monte_carlo", "n": 2000, "solver_check": 20}


def test_the_study_function_equals_the_stage(run, tmp_path) -> None:
    unit = "study[study=bump_stop]"
    run.pipeline.run(unit, set={"study.bootstrap": 100})
    stage = Path(run.pipeline.dir(unit, "evaluations.parquet"))
    surrogate = Path(run.dir("surrogate", "surrogate.json"))
    out = tmp_path / "bump_stop"
    result = pino_mbd.study(
        surrogate, BUMP_STOP, out=out,
        coverage=0.9, seed=7, batch_size=8, bootstrap=100, confidence=0.95,
    )
    assert str(out / "evaluations.parquet") in result["files"]
    for name in ("evaluations.parquet", "summary.parquet"):
        a, b = pl.read_parquet(out / name), pl.read_parquet(stage / name)
        assert a.height > 0
        assert_bit_identical(a, b)
    assert pl.read_parquet(out / "evaluations.parquet").height == BUMP_STOP["n"]
