#!/usr/bin/env python3
"""Reads every Parquet artifact of a pino-mbd pipeline run with pyarrow, polars and DuckDB.

    python3 tests/interop/check_parquet.py WORKSPACE [--file PREDICTIONS.parquet ...]

WORKSPACE is a directory where `pipeline run` ran (its store, `artifacts/objects/*/out`, holds
the files; every object in it is checked, so use a fresh workspace). `--file` adds files written
outside the store (`predict --out`). For every file:

- the schema, read by each of the three libraries: column names, types, and each column's unit
  (Arrow field metadata `unit`), against the spec stated here, independently of the Rust unit
  table (crates/pino-data/src/units.rs);
- the provenance (key-value metadata): version, stage, unit and parameters, equal to what the
  orchestrator gave the stage (the object's context.json), and the same through pyarrow, polars
  and DuckDB;
- the content: the three libraries read the same values.

Then one figure per file type is recomputed from the data with a different library than the
writer used (a DuckDB query for the peak wheel-rail force per sample against indices.parquet,
time grids and parameter ranges with polars, ...), and docs/outputs.md's "Reading the outputs"
examples (the ```python blocks after a `<!-- checked by tests/interop -->` line) are run in the
workspace, in order, in one session, so they cannot rot.

Exit 0 when everything holds, 1 with the first failure otherwise.
Needs `pip install -r tests/interop/requirements.txt`.
"""

import argparse
import json
import math
import os
import re
import sys
import tomllib
import warnings
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

try:
    import duckdb
    import numpy as np
    import pandas as pd
    import polars as pl
    import pyarrow
    import pyarrow.parquet as pq
    from SALib.analyze import sobol as salib_sobol
except ImportError as e:
    sys.exit(f"check_parquet: {e}: run `pip install -r tests/interop/requirements.txt`")

REPO = Path(__file__).resolve().parents[2]
README_MARK = "<!-- checked by tests/interop -->"
# The page holding the "Reading the outputs" examples.
EXAMPLES = "docs/outputs.md"


class Failure(Exception):
    """A property that does not hold; the message names the file and the column."""


def check(cond, message):
    if not cond:
        raise Failure(message)


def close(a, b, rel, what):
    check(
        math.isclose(a, b, rel_tol=rel, abs_tol=0.0) or (a == b),
        f"{what}: {a!r} != {b!r} (relative tolerance {rel})",
    )


def lit(path):
    """A SQL string literal of a path."""
    return "'" + str(path).replace("'", "''") + "'"


def lits(paths):
    return "[" + ", ".join(lit(p) for p in paths) + "]"


# ---- The expected schema: the spec (docs/model.md, docs/outputs.md), stated independently ----------

DOFS = ["z_c", "beta_c", "z_t1", "beta_t1", "z_t2", "beta_t2", "z_w1", "z_w2", "z_w3", "z_w4"]
RAIL = [f"z_r{i}" for i in range(1, 5)]
ETA = [f"eta_{i}" for i in range(1, 5)]
FORCES = [f"p_{i}" for i in range(1, 5)]
PARAM_UNITS = {
    "m_c": "kg", "j_c": "kg m^2", "m_t": "kg", "j_t": "kg m^2", "m_w": "kg",
    "k_p": "N/m", "c_p": "N s/m", "k_s": "N/m", "c_s": "N s/m", "l_c": "m", "l_t": "m",
    "v_kmh": "km/h", "k_f": "N/m", "c_f": "N s/m",
}
CONSTANT_UNITS = {  # provenance.parquet: the run controls of simulate
    "dt": "s", "duration": "s", "output_every": "1", "x0": "m",
    "startup_zero_fraction": "1", "startup_ramp_fraction": "1",
}
I64, F64, STR, BOOL = "int64", "double", "string", "bool"
TYPES = {  # pyarrow name -> (polars dtype, DuckDB type)
    I64: (pl.Int64, "BIGINT"),
    F64: (pl.Float64, "DOUBLE"),
    STR: (pl.String, "VARCHAR"),
    BOOL: (pl.Boolean, "BOOLEAN"),
}
# The columns whose absent values are nulls (every other column has a value in every row):
# by name in every file, and `factor` of a sensitivity study's evaluations and solver runs (null
# in the A and B blocks).
NULLABLE = {"outside_training_range", "failed", "solver_failure", "verdict", "worst_cell"}


def nullable(kind, name):
    return name in NULLABLE or name.endswith("_verdict") or (name == "factor" and kind in ("sensitivity/evaluations.parquet", "sensitivity/solver.parquet"))


def dof_unit(dof, order):
    base = "rad" if dof.startswith("beta") else "m"
    return base + ["", "/s", "/s^2"][order]


def signals(outputs):
    """outputs, then the vehicle DOFs' velocities and accelerations, then eta under the wheels."""
    return (
        outputs
        + [(d + "_v", F64, dof_unit(d, 1)) for d in DOFS]
        + [(d + "_a", F64, dof_unit(d, 2)) for d in DOFS]
        + [(e, F64, "m") for e in ETA]
    )


SOLUTIONS = [(d, F64, dof_unit(d, 0)) for d in DOFS] + [(r, F64, "m") for r in RAIL]
PCT = [
    "solutions_pct", "first_derivatives_pct", "second_derivatives_pct", "contact_forces_pct",
    "peak_contact_force_error_pct_w", "paper_solutions_pct", "paper_first_derivatives_pct",
    "paper_second_derivatives_pct",
]
# File type -> (stage, [(column, type, unit)]); None: columns checked by the type's own rules.
EXPECTED = {
    "params.parquet": (
        "sample-params",
        [("sample_id", I64, "1"), ("split", STR, "1")]
        + [(p, F64, u) for p, u in PARAM_UNITS.items()],
    ),
    "irregularity.parquet": (
        "irregularity",
        [("sample_id", I64, "1"), ("x", F64, "m"), ("eta", F64, "m")],
    ),
    "simulation.parquet": (
        "simulate",
        [("sample_id", I64, "1"), ("t", F64, "s")]
        + signals(SOLUTIONS)
        + [(p, F64, "N") for p in FORCES],
    ),
    "ranges.parquet": (
        "sample-params",
        [("name", STR, "1"), ("unit", STR, "1"), ("min", F64, "{unit}"), ("max", F64, "{unit}")],
    ),
    "failures.parquet": ("simulate", [("sample_id", I64, "1"), ("reason", STR, "1")]),
    "provenance.parquet": (
        "simulate",
        [("name", STR, "1"), ("value", F64, "{unit}"), ("unit", STR, "1")],
    ),
    "weights.parquet": (
        "weights",
        [("sample_id", I64, "1")]
        + [(f"phi_{d}", F64, "N m" if d.startswith("beta") else "N") for d in DOFS],
    ),
    "history.parquet": (
        "train",
        [("epoch", I64, "1"), ("step", I64, "1")]
        + [(c, F64, "1") for c in ["lr", "loss_total", "loss_data", "loss_deriv", "loss_ode",
                                    "val_solution", "val_first", "val_second"]],
    ),
    "table4.parquet": (
        "evaluate",
        [("algorithm", I64, "1"), ("name", STR, "1"), ("depth", I64, "1"), ("split", STR, "1")]
        + [(c, F64, "%") for c in PCT]
        + [("samples", I64, "1")],
    ),
    "channel_errors.parquet": (
        "evaluate",
        [("algorithm", I64, "1"), ("channel", STR, "1"), ("unit", STR, "1"),
         ("rel_l2_pct", F64, "%"), ("rms_error", F64, "{unit}"), ("rms_exact", F64, "{unit}"),
         ("worst_sample_id", I64, "1"), ("worst_rel_l2_pct", F64, "%"),
         ("peak_error_pct_w", F64, "%")],
    ),
    # The calibrated intervals on the test split (docs/uncertainty.md).
    "coverage.parquet": (
        "evaluate",
        [("algorithm", I64, "1"), ("kind", STR, "1"), ("quantity", STR, "1"), ("unit", STR, "1"),
         ("normaliser", STR, "1"), ("chosen", BOOL, "1"), ("level", F64, "1"),
         ("n_calibration", I64, "1"), ("n_test", I64, "1"), ("coverage", F64, "1"),
         ("mean_width", F64, "{unit}"), ("width_over_std", F64, "1")],
    ),
    "coverage_conditional.parquet": (
        "evaluate",
        [("algorithm", I64, "1"), ("kind", STR, "1"), ("quantity", STR, "1"), ("level", F64, "1"),
         ("group", STR, "1"), ("bin", STR, "1"), ("n", I64, "1"), ("coverage", F64, "1")],
    ),
    # The surrogate against the solver, per routed quantity (docs/uncertainty.md).
    "surrogate_errors.parquet": (
        "evaluate",
        [("kind", STR, "1"), ("quantity", STR, "1"), ("unit", STR, "1"), ("member", STR, "1"),
         ("n", I64, "1"), ("mean_rel_error_pct", F64, "%"), ("worst_rel_error_pct", F64, "%"),
         ("worst_rel_sample_id", I64, "1"), ("level", F64, "1"), ("coverage", F64, "1"),
         ("mean_width", F64, "{unit}"), ("width_over_std", F64, "1"),
         ("worst_cell_coverage", F64, "1"), ("worst_cell", STR, "1")],
    ),
    # The indices (docs/indices.md) own their columns: checked by PARTIAL below.
    "indices.parquet": ("indices", None),
    "indices_errors.parquet": ("evaluate", None),
    "indices_samples.parquet": ("evaluate", None),
    # The studies (docs/studies.md), keyed by their kind: the evaluations and solver checks own
    # their columns (the parameters and indices of the description); the summaries are fixed.
    "monte_carlo/evaluations.parquet": ("study", None),
    "monte_carlo/solver.parquet": ("study", None),
    "monte_carlo/summary.parquet": (
        "study",
        [("index", STR, "1"), ("unit", STR, "1"), ("source", STR, "1"), ("n", I64, "1")]
        + [(f"{stat}{side}", F64, "{unit}") for stat in ["mean", "std", "q05", "q50", "q95", "q99"]
           for side in ["", "_lo", "_hi"]]
        + [("limit", F64, "{unit}"), ("p_exceed", F64, "1"), ("p_exceed_lo", F64, "1"),
           ("p_exceed_hi", F64, "1"), ("p_surrogate_lo", F64, "1"), ("p_surrogate_hi", F64, "1")],
    ),
    "sensitivity/evaluations.parquet": ("study", None),
    "sensitivity/solver.parquet": ("study", None),
    "sensitivity/sobol.parquet": (
        "study",
        [("index", STR, "1"), ("source", STR, "1"), ("n", I64, "1"), ("factor", STR, "1")]
        + [(c, F64, "1") for c in ["S1", "S1_lo", "S1_hi", "ST", "ST_lo", "ST_hi", "rank"]],
    ),
    "sensitivity/convergence.parquet": (
        "study",
        [("index", STR, "1"), ("n", I64, "1"), ("factor", STR, "1"), ("S1", F64, "1"), ("ST", F64, "1")],
    ),
    "optimise/history.parquet": ("study", None),
    "optimise/evaluations.parquet": ("study", None),
    "optimise/solver.parquet": ("study", None),
    "optimise/optimum.parquet": ("study", None),
    "predict": (
        "predict",
        [("set", I64, "1"), ("t", F64, "s")] + signals(SOLUTIONS + [(p, F64, "N") for p in FORCES])
        + [("outside_training_range", STR, "1")],
    ),
}
# Files whose columns their stage defines: each column must have a unit, and these must be there
# (the contract the checks below and the README use).
PARTIAL = {
    "indices.parquet": [("sample_id", I64, "1"), ("peak_wheel_rail_force_kn", F64, "kN")],
    "indices_errors.parquet": [("algorithm", I64, "1"), ("index", STR, "1"), ("unit", STR, "1")],
    "monte_carlo/evaluations.parquet": [
        ("design", I64, "1"), ("excitation", I64, "1"), ("wheel_load_reduction_rate", F64, "1"),
        ("wheel_load_reduction_rate_lo", F64, "1"), ("wheel_load_reduction_rate_hi", F64, "1"),
        ("extrapolated", BOOL, "1"), ("solver_checked", BOOL, "1"),
    ],
    "monte_carlo/solver.parquet": [
        ("design", I64, "1"), ("excitation", I64, "1"), ("peak_wheel_rail_force_kn", F64, "kN"),
        ("peak_wheel_rail_force_kn_surrogate", F64, "kN"), ("solver_failure", STR, "1"),
    ],
    "sensitivity/evaluations.parquet": [
        ("row", I64, "1"), ("position", I64, "1"), ("block", STR, "1"), ("factor", STR, "1"),
        ("excitation", I64, "1"), ("sperling_wz_centre", F64, "1"), ("extrapolated", BOOL, "1"),
        ("solver_checked", BOOL, "1"),
    ],
    "sensitivity/solver.parquet": [
        ("row", I64, "1"), ("position", I64, "1"), ("block", STR, "1"), ("factor", STR, "1"),
        ("excitation", I64, "1"), ("sperling_wz_centre", F64, "1"),
        ("sperling_wz_centre_surrogate", F64, "1"), ("solver_failure", STR, "1"),
    ],
    "optimise/history.parquet": [
        ("candidate", I64, "1"), ("start", I64, "1"), ("evaluation", I64, "1"),
        ("objective", F64, "m/s^2"), ("feasible", BOOL, "1"), ("penalised", F64, "1"),
    ],
    "optimise/evaluations.parquet": [
        ("candidate", I64, "1"), ("excitation", I64, "1"), ("car_body_acc_rms_centre_ms2", F64, "m/s^2"),
        ("extrapolated", BOOL, "1"), ("solver_checked", BOOL, "1"),
    ],
    "optimise/solver.parquet": [
        ("candidate", I64, "1"), ("role", STR, "1"), ("excitation", I64, "1"),
        ("car_body_acc_rms_centre_ms2_surrogate", F64, "m/s^2"), ("solver_failure", STR, "1"),
    ],
    "optimise/optimum.parquet": [
        ("candidate", I64, "1"), ("role", STR, "1"), ("source", STR, "1"), ("objective", F64, "m/s^2"),
        ("feasible", BOOL, "1"),
    ],
    "indices_samples.parquet": [
        ("algorithm", I64, "1"), ("sample_id", I64, "1"),
        ("peak_wheel_rail_force_kn", F64, "kN"), ("peak_wheel_rail_force_kn_exact", F64, "kN"),
    ],
}
# Optional artifacts: checked when present, not required.
OPTIONAL = {"predict", "indices_errors.parquet", "indices_samples.parquet"}


def project_version():
    with open(REPO / "Cargo.toml", "rb") as f:
        return tomllib.load(f)["workspace"]["package"]["version"]


@dataclass
class Artifact:
    path: Path
    kind: str
    params: dict
    meta: dict


# ---- Per file: schema, provenance, the same content through the three readers -------------


def check_file(path, kind, context, version, commands):
    stage, columns = EXPECTED[kind]
    where = f"{path} ({kind})"

    # pyarrow: names, types, field units, file metadata.
    schema = pq.read_schema(path)
    fields = [(f.name, str(f.type), (f.metadata or {}).get(b"unit", b"").decode()) for f in schema]
    for name, _, unit in fields:
        check(unit != "", f"{where}: column `{name}` has no `unit` field metadata")
    for f in schema:
        want = nullable(kind, f.name)
        check(f.nullable == want, f"{where}: column `{f.name}` nullable = {f.nullable}, the spec says {want}")
    if columns is None:
        names = [f[0] for f in fields]
        for col in PARTIAL[kind]:
            check(col[0] in names, f"{where}: no column `{col[0]}` (columns: {names})")
            check(fields[names.index(col[0])] == col, f"{where}: {fields[names.index(col[0])]} != {col}")
        columns = fields
    check(
        fields == columns,
        f"{where}: schema differs from the spec:\n"
        + "\n".join(f"  {got} != {want}" for got, want in zip(fields, columns) if got != want)
        + f"\n  ({len(fields)} columns, {len(columns)} expected)",
    )
    meta = {k.decode(): v.decode() for k, v in (schema.metadata or {}).items()}
    for key in ["pino.version", "pino.stage", "pino.unit", "pino.params", "pino.column_units"]:
        check(key in meta, f"{where}: no `{key}` in the file's metadata (has {sorted(meta)})")
    check(meta["pino.version"] == version, f"{where}: pino.version {meta['pino.version']} != {version}")
    # The file names the pipeline stage that wrote it (the store's unit), and that stage runs the
    # binary this kind of file comes from (`train-rates` runs `train`).
    named = stage if context is None else context["stage"].split("[")[0]
    check(meta["pino.stage"] == named, f"{where}: pino.stage {meta['pino.stage']!r} != {named!r}")
    ran = commands.get(named, named)
    check(ran == stage, f"{where}: written by stage `{named}`, which runs `{ran}`, not `{stage}`")
    units = json.loads(meta["pino.column_units"])
    check(units == {n: u for n, _, u in columns}, f"{where}: pino.column_units {units} disagrees with the fields")
    params = json.loads(meta["pino.params"])
    check(isinstance(params, dict), f"{where}: pino.params is not a JSON object")
    if context is not None:
        shard = context.get("shard", {"index": 0, "count": 1})
        unit = context["stage"] + (f"#{shard['index']}" if shard["count"] > 1 else "")
        check(meta["pino.unit"] == unit, f"{where}: pino.unit {meta['pino.unit']!r}, the store ran it as {unit!r}")
        check(params == context["params"], f"{where}: pino.params differ from the context's params")

    # polars: names, dtypes, key-value metadata.
    pl_schema = pl.read_parquet_schema(path)
    check(list(pl_schema.keys()) == [c[0] for c in columns], f"{where}: polars sees columns {list(pl_schema)}")
    for name, typ, _ in columns:
        check(pl_schema[name] == TYPES[typ][0], f"{where}: polars reads `{name}` as {pl_schema[name]}")
    pl_meta = pl.read_parquet_metadata(path)
    for key, value in meta.items():
        check(pl_meta.get(key) == value, f"{where}: polars metadata `{key}` = {pl_meta.get(key)!r}")

    # DuckDB: names, types, key-value metadata.
    described = duckdb.sql(f"DESCRIBE SELECT * FROM read_parquet({lit(path)})").fetchall()
    got = [(row[0], row[1]) for row in described]
    want = [(n, TYPES[t][1]) for n, t, _ in columns]
    check(got == want, f"{where}: DuckDB describes {got}")
    kv = {
        k.decode(): v.decode()
        for k, v in duckdb.sql(f"SELECT key, value FROM parquet_kv_metadata({lit(path)})").fetchall()
    }
    for key, value in meta.items():
        check(kv.get(key) == value, f"{where}: DuckDB metadata `{key}` = {kv.get(key)!r}")

    # The same values through all three.
    a = pq.read_table(path).to_pandas()
    p = pl.read_parquet(path).to_pandas()
    d = duckdb.sql(f"SELECT * FROM read_parquet({lit(path)})").df()
    check(len(a) > 0 or kind in ("failures.parquet",), f"{where}: no rows")
    for other, who in [(p, "polars"), (d, "DuckDB")]:
        try:
            pd.testing.assert_frame_equal(a, other, check_dtype=False, check_exact=True)
        except AssertionError as e:
            raise Failure(f"{where}: pyarrow and {who} read different values: {e}") from None
    return Artifact(path, kind, params, meta)


# ---- One figure per file type, recomputed independently ------------------------------------


def one(arts, kind):
    check(len(arts[kind]) == 1, f"expected one {kind}, found {len(arts[kind])}")
    return arts[kind][0]


def window_filter(start_fraction):
    """SQL keeping a sample's rows from row floor(f * n) on (the start-up window dropped)."""
    return (
        "QUALIFY row_number() OVER (PARTITION BY sample_id ORDER BY t) - 1 >= "
        f"floor({float(start_fraction)!r} * count(*) OVER (PARTITION BY sample_id))"
    )


def recompute(arts, say):
    params = one(arts, "params.parquet")
    sims = [a.path for a in arts["simulation.parquet"]]
    sim_params = arts["simulation.parquet"][0].params
    pp = params.params

    # params: the split sizes (DuckDB) and every parameter inside its range (polars).
    counts = dict(duckdb.sql(f"SELECT split, count(*) FROM read_parquet({lit(params.path)}) GROUP BY split").fetchall())
    want = {s: pp.get(f"n_{s}", 0) for s in ["train", "validation", "test", "calibration"] if pp.get(f"n_{s}", 0) > 0}
    check(counts == want, f"{params.path}: split sizes {counts} != the parameters' {want}")
    df = pl.read_parquet(params.path)
    for name, r in pp.get("ranges", {}).items():
        lo, hi = r if isinstance(r, list) else [r["nominal"] * f for f in r["factor"]]
        got = (df[name].min(), df[name].max())
        check(lo <= got[0] and got[1] <= hi, f"{params.path}: `{name}` spans {got}, outside [{lo}, {hi}]")
    say(f"params: split sizes {counts} and {len(pp.get('ranges', {}))} ranges")

    # irregularity: points per profile and x = k dx (polars), one profile per sample (DuckDB).
    irr = one(arts, "irregularity.parquet")
    ip = irr.params
    per = (
        pl.read_parquet(irr.path)
        .group_by("sample_id", maintain_order=True)
        .agg(pl.len().alias("n"), (pl.col("x") - pl.int_range(pl.len()) * ip["dx"]).abs().max().alias("err"))
    )
    n_points = round(ip["length"] / ip["dx"])
    check(per["n"].unique().to_list() == [n_points], f"{irr.path}: points per profile {per['n'].unique().to_list()} != length/dx = {n_points}")
    check(per["err"].max() <= 1e-9 * ip["length"], f"{irr.path}: x is not k * dx (off by {per['err'].max()} m)")
    missing = duckdb.sql(
        f"SELECT count(*) FROM read_parquet({lit(params.path)}) p ANTI JOIN "
        f"(SELECT DISTINCT sample_id FROM read_parquet({lit(irr.path)})) USING (sample_id)"
    ).fetchall()[0][0]
    check(missing == 0, f"{irr.path}: {missing} samples of params.parquet have no profile")
    say(f"irregularity: {len(per)} profiles of {n_points} points at dx = {ip['dx']} m")

    # simulation: the output time grid (polars): a step of dt * output_every, from t = 0.
    step = sim_params["dt"] * sim_params["output_every"]
    grid = (
        pl.scan_parquet(sims)
        .group_by("sample_id")
        .agg(pl.len().alias("n"), pl.col("t").min().alias("t0"), (pl.col("t").diff().drop_nulls() - step).abs().max().alias("err"))
        .collect()
    )
    check(grid["t0"].max() == 0.0, f"simulation: a sample does not start at t = 0")
    check(grid["err"].max() <= 1e-9 * step, f"simulation: time step differs from dt * output_every = {step} s by {grid['err'].max()}")
    n_rows = round(sim_params["duration"] / step)
    check(set(grid["n"].to_list()) <= {n_rows, n_rows + 1}, f"simulation: rows per sample {set(grid['n'])}, duration / step = {n_rows}")
    say(f"simulation: {len(grid)} samples on a {step} s grid ({grid['n'][0]} rows each)")

    # failures: simulated and failed samples partition params.parquet (DuckDB).
    fails = [a.path for a in arts["failures.parquet"]]
    row = duckdb.sql(
        f"WITH s AS (SELECT DISTINCT sample_id FROM read_parquet({lits(sims)})), "
        f"f AS (SELECT sample_id FROM read_parquet({lits(fails)})), "
        f"a AS (SELECT sample_id FROM s UNION ALL SELECT sample_id FROM f) "
        f"SELECT (SELECT count(*) FROM a), (SELECT count(DISTINCT sample_id) FROM a), "
        f"(SELECT count(*) FROM read_parquet({lit(params.path)}) p SEMI JOIN a USING (sample_id)), "
        f"(SELECT count(*) FROM read_parquet({lit(params.path)}))"
    ).fetchall()[0]
    check(row[0] == row[1] == row[2] == row[3], f"failures: simulated + failed samples {row[:3]} do not partition the {row[3]} samples")
    say(f"failures: {row[0] - len(grid)} failed, {len(grid)} simulated of {row[3]}")

    # provenance: the constants are the simulate stage's parameters, with their units (pandas).
    for a in arts["provenance.parquet"]:
        t = pd.read_parquet(a.path)
        for name, value, unit in zip(t["name"], t["value"], t["unit"]):
            check(value == a.params[name], f"{a.path}: {name} = {value}, the stage ran with {a.params[name]}")
            check(unit == CONSTANT_UNITS[name], f"{a.path}: {name} in {unit!r}, expected {CONSTANT_UNITS[name]!r}")
    say(f"provenance: {len(arts['provenance.parquet'])} records equal the stage parameters")

    # weights: phi for exactly the simulated training samples (DuckDB), all positive.
    w = one(arts, "weights.parquet")
    row = duckdb.sql(
        f"WITH s AS (SELECT DISTINCT sample_id FROM read_parquet({lits(sims)}) sim "
        f"JOIN read_parquet({lit(params.path)}) p USING (sample_id) WHERE split = 'train') "
        f"SELECT (SELECT count(*) FROM s), (SELECT count(*) FROM read_parquet({lit(w.path)})), "
        f"(SELECT count(*) FROM read_parquet({lit(w.path)}) SEMI JOIN s USING (sample_id)), "
        f"(SELECT min(least({', '.join(f'phi_{d}' for d in DOFS)})) FROM read_parquet({lit(w.path)}))"
    ).fetchall()[0]
    check(row[0] == row[1] == row[2], f"{w.path}: {row[1]} rows, {row[2]} of the {row[0]} simulated training samples")
    check(row[3] > 0, f"{w.path}: a phi is not positive ({row[3]})")
    say(f"weights: phi for the {row[0]} simulated training samples")

    # history: one row per epoch, the step-decay learning rate (polars).
    for h in arts["history.parquet"]:
        hp = h.params
        df = pl.read_parquet(h.path)
        check(df["epoch"].to_list() == list(range(1, hp["epochs"] + 1)), f"{h.path}: epochs {df['epoch'].to_list()}")
        for e, lr in zip(df["epoch"], df["lr"]):
            want = hp["learning_rate"] * hp["lr_decay"] ** ((e - 1) // hp["lr_decay_every"])
            close(lr, want, 1e-12, f"{h.path}: lr of epoch {e}")
    say(f"history: {len(arts['history.parquet'])} models, epochs and learning rates")

    # The models' window (every model is trained and scored on the same one).
    starts = {h.params.get("startup_fraction", 0.0) for h in arts["history.parquet"]}
    check(len(starts) == 1, f"models trained on different windows: {starts}")
    startup = starts.pop()

    # table4 and channel_errors of the evaluation (`evaluate`, Table 4 of the paper's five
    # algorithms): the scored samples (DuckDB on params + simulation), the peak force error as
    # the mean over the four wheels, the RMS contact force recomputed; every model of `train`
    # scored by exactly one evaluation (the other candidates, with rate outputs or a force
    # term, are scored by the surrogate's report where they answer).
    check(arts["table4.parquet"], "no table4.parquet")
    scored_models = 0
    for t4 in arts["table4.parquet"]:
        ces = [c for c in arts["channel_errors.parquet"] if c.path.parent == t4.path.parent]
        check(len(ces) == 1, f"{t4.path}: expected one channel_errors.parquet beside it, found {len(ces)}")
        ce = ces[0]
        split = duckdb.sql(f"SELECT DISTINCT split FROM read_parquet({lit(t4.path)})").fetchall()
        check(len(split) == 1, f"{t4.path}: several splits {split}")
        split = split[0][0]
        scored = duckdb.sql(
            f"SELECT count(DISTINCT sample_id) FROM read_parquet({lits(sims)}) sim "
            f"JOIN read_parquet({lit(params.path)}) p USING (sample_id) WHERE split = '{split}'"
        ).fetchall()[0][0]
        samples = duckdb.sql(f"SELECT DISTINCT samples FROM read_parquet({lit(t4.path)})").fetchall()
        check(samples == [(scored,)], f"{t4.path}: samples {samples}, {scored} simulated {split} samples")
        rows = duckdb.sql(
            f"SELECT t.algorithm, t.peak_contact_force_error_pct_w, avg(c.peak_error_pct_w) "
            f"FROM read_parquet({lit(t4.path)}) t JOIN read_parquet({lit(ce.path)}) c USING (algorithm) "
            f"WHERE c.channel IN ('p_1', 'p_2', 'p_3', 'p_4') GROUP BY ALL ORDER BY 1"
        ).fetchall()
        models = duckdb.sql(f"SELECT count(*) FROM read_parquet({lit(t4.path)}) WHERE algorithm > 0").fetchall()[0][0]
        check(len(rows) == models, f"{t4.path}: peak force rows {rows} for {models} models")
        scored_models += models
        for alg, table, mean in rows:
            close(table, mean, 1e-12, f"{t4.path}: algorithm {alg} peak force error vs channel_errors")
        rms = dict(duckdb.sql(
            f"SELECT 'p_' || i, sqrt(avg(power(CASE i WHEN 1 THEN p_1 WHEN 2 THEN p_2 WHEN 3 THEN p_3 ELSE p_4 END / 1000, 2))) "
            f"FROM (SELECT * FROM read_parquet({lits(sims)}) sim JOIN read_parquet({lit(params.path)}) p USING (sample_id) "
            f"WHERE split = '{split}' {window_filter(startup)}), range(1, 5) r(i) GROUP BY 1"
        ).fetchall())
        got = duckdb.sql(
            f"SELECT algorithm, channel, unit, rms_exact FROM read_parquet({lit(ce.path)}) "
            f"WHERE channel IN ('p_1', 'p_2', 'p_3', 'p_4')"
        ).fetchall()
        check(len(got) == 4 * len(rows), f"{ce.path}: contact-force rows {got}")
        for alg, channel, unit, value in got:
            check(unit == "kN", f"{ce.path}: {channel} in {unit}")
            close(value, rms[channel], 1e-9, f"{ce.path}: algorithm {alg} rms_exact of {channel} (kN)")
    paper = [h for h in arts["history.parquet"] if not h.params.get("rate_outputs") and not h.params.get("force_weight")]
    check(scored_models == len(paper), f"{scored_models} models scored, {len(paper)} trained by `train`")
    say(f"evaluate: {len(arts['table4.parquet'])} evaluations of {scored} {split} samples, peak force error = mean over wheels, RMS contact force")

    # indices: the peak wheel-rail force per sample, a DuckDB query over simulation.parquet.
    ix = one(arts, "indices.parquet")
    start = ix.params.get("window_start_fraction", 0.0)
    # ... from the later of the fraction's row and the description's `indices_from` (s), which
    # `indices.json` beside the table states.
    with open(os.path.join(os.path.dirname(ix.path), "indices.json")) as f:
        t_from = float(json.load(f)["parameters"]["indices_from_s"])
    peaks = dict(duckdb.sql(
        f"SELECT sample_id, max(greatest(p_1, p_2, p_3, p_4)) / 1000 FROM "
        f"(SELECT * FROM read_parquet({lits(sims)}) {window_filter(start)}) "
        f"WHERE t >= {t_from!r} - 1e-9 GROUP BY sample_id"
    ).fetchall())
    got = duckdb.sql(f"SELECT sample_id, peak_wheel_rail_force_kn FROM read_parquet({lit(ix.path)})").fetchall()
    check(got, f"{ix.path}: no rows")
    for sid, value in got:
        check(sid in peaks, f"{ix.path}: sample {sid} is not in the simulation")
        close(value, peaks[sid], 1e-12, f"{ix.path}: peak_wheel_rail_force_kn of sample {sid}")
    say(f"indices: peak wheel-rail force of {len(got)} samples (window from {start} of each record, t >= {t_from} s)")

    # coverage of every evaluation: one row per algorithm, kind, quantity, normaliser and level
    # (a rate output beside its difference is `NAME (output)`); a higher level never covers
    # less nor is narrower (DuckDB window over levels); coverages are fractions of the scored
    # test samples.
    check(arts["coverage.parquet"], "no coverage.parquet")
    n_cov = 0
    for cov in arts["coverage.parquet"]:
        bad = duckdb.sql(
            f"SELECT algorithm, kind, quantity, normaliser, level, coverage, mean_width, n_test FROM ("
            f"SELECT *, lag(coverage) OVER w AS c0, lag(mean_width) OVER w AS w0 FROM read_parquet({lit(cov.path)}) "
            f"WINDOW w AS (PARTITION BY algorithm, kind, quantity, normaliser ORDER BY level)) "
            f"WHERE coverage < c0 OR mean_width < w0 OR abs(coverage * n_test - round(coverage * n_test)) > 1e-9 "
            f"OR n_test != {scored}"
        ).fetchall()
        check(not bad, f"{cov.path}: rows break monotonicity in the level or the test count: {bad[:3]}")
        twice = duckdb.sql(
            f"SELECT algorithm, kind, quantity, normaliser, level, count(*) FROM read_parquet({lit(cov.path)}) "
            f"GROUP BY ALL HAVING count(*) > 1"
        ).fetchall()
        check(not twice, f"{cov.path}: (algorithm, kind, quantity, normaliser, level) is not a key: {twice[:3]}")
        n_cov += duckdb.sql(f"SELECT count(*) FROM read_parquet({lit(cov.path)})").fetchall()[0][0]
    say(f"coverage: {n_cov} rows monotone in the level, fractions of the {scored} test samples")

    # The surrogate's report: one row per quantity of its manifest, each scored by the member
    # the manifest routes it to, on every scored test sample.
    se = one(arts, "surrogate_errors.parquet")
    context = json.loads((se.path.parent.parent / "context.json").read_text())
    sur = [Path(context["inputs"]["surrogate"][0]) / "surrogate.json"]
    with open(sur[0]) as f:
        manifest = json.load(f)
    routes = {("index", r["name"]): r["member"] for r in manifest["indices"]}
    routes.update({("channel", r["name"]): r["member"] for r in manifest["channels"]})
    rows = duckdb.sql(f"SELECT kind, quantity, member, n, coverage FROM read_parquet({lit(se.path)})").fetchall()
    check({(k, q): m for k, q, m, _, _ in rows} == routes, f"{se.path}: members differ from {sur[0]}'s routes")
    check(all(n == scored and 0.0 <= c <= 1.0 for *_, n, c in rows), f"{se.path}: counts or coverages {rows[:3]}")
    say(f"surrogate: {len(rows)} quantities, each scored by the member surrogate.json routes it to")

    # study: every exceedance probability and its surrogate bounds recomputed from the
    # evaluations in DuckDB, exactly.
    ev, sm = one(arts, "monte_carlo/evaluations.parquet"), one(arts, "monte_carlo/summary.parquet")
    rows = duckdb.sql(
        f'SELECT "index", "limit", p_exceed, p_surrogate_lo, p_surrogate_hi FROM read_parquet({lit(sm.path)}) '
        f"""WHERE source = 'surrogate' AND NOT isnan("limit")"""
    ).fetchall()
    check(rows, f"{sm.path}: no exceedance row")
    for index, limit, p, lo, hi in rows:
        got = duckdb.sql(
            f'SELECT avg(("{index}" > {limit!r})::DOUBLE), avg(("{index}_lo" > {limit!r})::DOUBLE), '
            f'avg(("{index}_hi" > {limit!r})::DOUBLE) FROM read_parquet({lit(ev.path)})'
        ).fetchall()[0]
        check(got == (p, lo, hi), f"{sm.path}: P({index} > {limit}) {p, lo, hi}, DuckDB {got}")
    say(f"study: {len(rows)} exceedance probabilities and their bounds recomputed from the evaluations")

    # sensitivity: every Sobol index of every source recomputed with SALib from the stored
    # outputs in SALib's order (the surrogate's on all rows and on the solver's, the solver's),
    # to 1e-10.
    ev, sv = one(arts, "sensitivity/evaluations.parquet"), one(arts, "sensitivity/solver.parquet")
    sb = pl.read_parquet(one(arts, "sensitivity/sobol.parquet").path)
    outputs = {
        "surrogate": pl.read_parquet(ev.path).sort(["row", "position"]),
        "solver": pl.read_parquet(sv.path).sort(["row", "position"]),
    }
    outputs["surrogate_reduced"] = outputs["surrogate"].filter(pl.col("solver_checked"))
    compared = 0
    for (index, source), est in sb.group_by(["index", "source"], maintain_order=True):
        factors = est["factor"].to_list()
        # One name per factor (the excitation's phases already one column of the design); an
        # array, as SALib 1.5.1's `pd.unique` needs under pandas 3.
        problem = {"num_vars": len(factors), "names": np.asarray(factors), "bounds": [[0.0, 1.0]] * len(factors)}
        y = outputs[source][index].to_numpy()
        check(len(y) == est["n"][0] * (len(factors) + 2), f"{ev.path}: {len(y)} outputs of `{index}` ({source})")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            got = salib_sobol.analyze(problem, y, calc_second_order=False, num_resamples=10, seed=1)
        for name in ["S1", "ST"]:
            diff = np.abs(np.asarray(got[name]) - est[name].to_numpy()).max()
            check(diff <= 1e-10, f"{index} ({source}): {name} differs from SALib's by {diff:.3g}")
        compared += 1
    say(f"sensitivity: S1 and ST of {compared} index-source pairs equal SALib's to 1e-10")

    # optimise: the optimum's objective, the mean of its evaluations (docs/studies.md's query),
    # and the best objective of the feasible candidates of the history.
    ev, op = one(arts, "optimise/evaluations.parquet"), one(arts, "optimise/optimum.parquet")
    hist = one(arts, "optimise/history.parquet")
    objective = ev.params["study"]["objective"]
    check(isinstance(objective, str), f"{ev.path}: the shipped optimisation has one index as objective")
    got, stored = duckdb.sql(
        f'SELECT avg(e."{objective}"), any_value(o.objective) FROM read_parquet({lit(ev.path)}) e '
        f"JOIN read_parquet({lit(op.path)}) o USING (candidate) "
        f"WHERE o.role = 'optimum' AND o.source = 'surrogate'"
    ).fetchall()[0]
    check(abs(got - stored) <= 1e-12 * abs(stored), f"{op.path}: optimum objective {stored}, DuckDB {got}")
    lowest = duckdb.sql(f"SELECT min(objective) FROM read_parquet({lit(hist.path)}) WHERE feasible").fetchall()[0][0]
    check(lowest == stored, f"{hist.path}: best feasible objective {lowest}, the optimum's {stored}")
    say(f"optimise: the optimum's objective {stored:.6g} recomputed from its evaluations, the history's best feasible")

    # predict: one block of rows per parameter set, on a uniform time grid (polars).
    for a in arts["predict"]:
        df = pl.read_parquet(a.path)
        sets = df["set"].unique(maintain_order=True).to_list()
        check(sets == list(range(len(a.params["sets"]))), f"{a.path}: sets {sets}, {len(a.params['sets'])} given")
        dt = df.filter(pl.col("set") == 0)["t"].diff().drop_nulls()
        check((dt - dt[0]).abs().max() <= 1e-9 * dt[0], f"{a.path}: time grid not uniform")
        say(f"predict: {len(sets)} sets x {len(dt) + 1} points")


# ---- The examples of docs/outputs.md ------------------------------------------------------------------


def readme_blocks():
    text = (REPO / EXAMPLES).read_text()
    blocks = re.findall(re.escape(README_MARK) + r"\n```python\n(.*?)\n```", text, re.S)
    check(len(blocks) >= 3, f"{EXAMPLES}: {len(blocks)} python blocks after `{README_MARK}`, expected the pandas, polars and DuckDB examples")
    for lib in ["pandas", "polars", "duckdb"]:
        check(any(re.search(rf"^import .*\b{lib}\b", b, re.M) for b in blocks), f"{EXAMPLES}: no checked example imports {lib}")
    return blocks


def run_readme(ws, say):
    blocks = readme_blocks()
    cwd = os.getcwd()
    os.chdir(ws)
    try:
        scope = {"__name__": "__readme__"}
        for i, block in enumerate(blocks, 1):
            try:
                exec(compile(block, f"{EXAMPLES} checked block {i}", "exec"), scope)
            except Exception as e:
                raise Failure(f"{EXAMPLES} checked block {i} fails in {ws}: {type(e).__name__}: {e}\n{block}") from e
    finally:
        os.chdir(cwd)
    say(f"{EXAMPLES}: {len(blocks)} examples ran")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("workspace", type=Path)
    ap.add_argument("--file", action="append", default=[], type=Path, help="a `predict` output")
    ap.add_argument("--commands", default="{}",
                    help="JSON {stage: the stage binary it runs}; a stage not named runs its namesake")
    args = ap.parse_args()
    commands = json.loads(args.commands)
    ws = args.workspace.resolve()
    print(f"pyarrow {pyarrow.__version__}, polars {pl.__version__}, duckdb {duckdb.__version__}, pandas {pd.__version__}")

    def say(line):
        print(f"ok: {line}", flush=True)

    try:
        version = project_version()
        objects = sorted((ws / "artifacts" / "objects").glob("*/out"))
        check(objects, f"{ws}: no artifacts/objects/*/out: run `pipeline run` there first")
        files = [
            (f, json.loads((out.parent / "context.json").read_text()))
            for out in objects
            for f in sorted(out.rglob("*.parquet"))
        ]
        files += [(f.resolve(), None) for f in args.file]
        arts = defaultdict(list)
        for path, context in files:
            kind = "predict" if context is None else path.name
            declared = (context or {}).get("params", {}).get("study")
            if isinstance(declared, dict) and "kind" in declared:  # a unit of any study stage
                kind = f"{declared['kind']}/{path.name}"
            check(kind in EXPECTED, f"{path}: an artifact this check does not know; state its schema in EXPECTED")
            arts[kind].append(check_file(path, kind, context, version, commands))
        say(f"{len(files)} files: names, types, units and provenance agree in pyarrow, polars and DuckDB")
        for kind in EXPECTED:
            if kind in OPTIONAL:
                continue
            if kind == "failures.parquet" or kind == "provenance.parquet":
                check(len(arts[kind]) == len(arts["simulation.parquet"]), f"one {kind} per simulate shard")
            check(arts[kind], f"no {kind} in {ws}/artifacts (is the `{EXPECTED[kind][0]}` stage in the pipeline?)")
        recompute(arts, say)
        run_readme(ws, say)
    except Failure as e:
        print(f"FAILED: {e}", file=sys.stderr)
        return 1
    print(f"interop: {len(files)} Parquet files checked with pyarrow, polars and DuckDB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
