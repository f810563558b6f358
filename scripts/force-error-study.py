#!/usr/bin/env python3
"""Where a vehicle-track model's wheel-rail force error lives (BENCHMARKS.md, "The wheel-load
reduction rate, second look").

    python3 scripts/force-error-study.py [-C WORKSPACE] [-f pipeline.yaml] [--bin-dir DIR]
                                         [--set STAGE.KEY=VALUE ...] [--split validation]
                                         STAGE [STAGE ...]

Each STAGE names a trained model of the pipeline (`train[algorithm=5]`, `train-rates`); the
models' predictions of every sample of the split (their own profiles, through the public
`pino_mbd.Model.predict`) are set beside the solver's contact forces (the description's
columns of kind `force`: `p_1..p_4` of the vehicle track), and for each model, then for the
mean of all of them (an ensemble), the script prints:

- the unloading rate `(W - min P) / W` over the force columns (the wheel-load reduction rate
  of the vehicle track), read from the description's `indices_from` as the indices are, the
  record's mean force standing for the static load W (it reproduces `evaluate`'s figure), as a
  mean relative error, with the mean signed error of the deepest unloading and of the peak
  (positive / negative: predicted extremes too shallow);
- that error with the error above / below `--cut-hz` (default 51 Hz, the default network's
  highest mode) taken out, i.e. what a perfect model of that band alone would give;
- the share of the force error's variance a linear filter of the excitations (`--lags` steps
  either side) predicts on the other half of the samples (fitted on even sample ids), and the
  reduction rate's error on that half after subtracting the filter's prediction.

Needs numpy and polars (the Python package's own dependency)."""

from __future__ import annotations

import argparse
import json
import os
import tempfile

import numpy as np
import polars as pl

import pino_mbd as pm

def reduction(p: np.ndarray, w: float, read: np.ndarray) -> float:
    """`(W - min_t,wheels P) / W` over the rows `read` (the description's `indices_from` on)."""
    return (w - p[read].min()) / w


def band_removed(truth: np.ndarray, pred: np.ndarray, dt: float, keep_below: bool, cut: float) -> np.ndarray:
    """`pred` with its error in one band removed: `keep_below` keeps the error below `cut` Hz."""
    err = np.fft.rfft(pred - truth, axis=0)
    f = np.fft.rfftfreq(truth.shape[0], dt)
    err[(f >= cut) if keep_below else (f < cut)] = 0.0
    return truth + np.fft.irfft(err, truth.shape[0], axis=0)


def on_times(solver: pl.DataFrame, prediction: pl.DataFrame) -> pl.DataFrame:
    """The solver's rows at the prediction's times (its interior points), matched to 1 us."""
    us = lambda df: df.with_columns((pl.col("t") * 1e6).round().cast(pl.Int64).alias("t_us"))  # noqa: E731
    return us(solver).join(us(prediction).select("t_us"), on="t_us", how="semi").sort("t_us")


def lagged(eta: np.ndarray, lags: int) -> np.ndarray:
    """Rows `lags..T-lags` of the excitations shifted by `-lags..lags` steps, and a constant."""
    t = eta.shape[0]
    cols = [np.roll(eta, k, axis=0)[lags : t - lags] for k in range(-lags, lags + 1)]
    return np.column_stack(cols + [np.ones(t - 2 * lags)])


def recorded_system(path: str) -> pm.System:
    """The description a dataset records (`system.json`: its file name, text and overrides)."""
    with open(path) as f:
        rec = json.load(f)
    with tempfile.TemporaryDirectory() as d:
        file = os.path.join(d, os.path.basename(rec["file"]))
        with open(file, "w") as f:
            f.write(rec["text"])
        return pm.System.load(file, rec.get("values") or None)


def study(
    pipe: pm.Pipeline, stages: list[str], split: str, cut_hz: float, lags: int
) -> dict[str, dict[str, float]]:
    """The figures the script prints, per model (and `mean of all` for several)."""
    params = pl.read_parquet(os.path.join(pipe.dir("sample-params", "params.parquet"), "params.parquet"))
    profiles = os.path.join(pipe.dir("irregularity", "irregularity.parquet"), "irregularity.parquet")
    sims = [p for p in pipe.show("simulate") if p.endswith("simulation.parquet")]
    system = recorded_system(os.path.join(os.path.dirname(sims[0]), "system.json"))
    kinds = system.columns
    forces = kinds.filter(pl.col("kind") == "force")["name"].to_list()
    excitations = kinds.filter(pl.col("kind") == "excitation")["name"].to_list()
    ids = params.filter(pl.col("split") == split)["sample_id"].sort().to_list()
    solver = (
        pl.concat([pl.read_parquet(s, columns=["sample_id", "t", *forces, *excitations]) for s in sims])
        .filter(pl.col("sample_id").is_in(ids))
        .sort("sample_id", "t")
    )
    truth = {i: g for (i,), g in solver.group_by("sample_id")}

    predictions = {}
    for stage in stages:
        model = pm.Model.load(pipe.dir(stage, "model.json"))
        predictions[stage] = {
            i: model.predict(params.filter(pl.col("sample_id") == i), excitation=profiles).select(
                ["t", *forces]
            )
            for i in ids
        }
    if len(stages) > 1:
        predictions["mean of all"] = {
            i: predictions[stages[0]][i].with_columns([sum(predictions[s][i][c] for s in stages) / len(stages) for c in forces])
            for i in ids
        }

    out = {}
    for name, per in predictions.items():
        rows, fir = [], []
        for i in ids:
            s = on_times(truth[i], per[i])
            y, f = s.select(forces).to_numpy(), per[i].select(forces).to_numpy()
            dt = float(s["t"][1] - s["t"][0])
            read = s["t"].to_numpy() >= system.indices_from - 0.5 * dt
            w = float(y.mean())
            rows.append(
                (
                    reduction(y, w, read),
                    reduction(f, w, read),
                    reduction(band_removed(y, f, dt, True, cut_hz), w, read),
                    reduction(band_removed(y, f, dt, False, cut_hz), w, read),
                    f[read].min() - y[read].min(),
                    f[read].max() - y[read].max(),
                )
            )
            fir.append((i, lagged(s.select(excitations).to_numpy(), lags), (f - y)[lags : len(y) - lags], y, f, w, read))
        r = np.array(rows)
        rel = lambda k: 100 * float(np.mean(np.abs(r[:, k] - r[:, 0]) / r[:, 0]))  # noqa: E731
        fit = [x for x in fir if x[0] % 2 == 0]
        held = [x for x in fir if x[0] % 2 == 1]
        coef, *_ = np.linalg.lstsq(np.concatenate([x[1] for x in fit]), np.concatenate([x[2] for x in fit]), rcond=None)
        e = np.concatenate([x[2] for x in held])
        left = e - np.concatenate([x[1] @ coef for x in held])
        before, after = [], []
        for _, x, _, y, f, w, read in held:
            g = f.copy()
            g[lags : len(f) - lags] -= x @ coef
            rt = reduction(y, w, read)
            before.append(abs(reduction(f, w, read) - rt) / rt)
            after.append(abs(reduction(g, w, read) - rt) / rt)
        out[name] = {
            "samples": len(ids),
            "reduction_error_pct": rel(1),
            "deepest_unloading_error_kn": float(r[:, 4].mean()) / 1e3,
            "peak_error_kn": float(r[:, 5].mean()) / 1e3,
            "above_cut_removed_pct": rel(2),
            "below_cut_removed_pct": rel(3),
            "filter_variance_share_pct": 100 * float(1 - (left**2).sum() / (e**2).sum()),
            "held_out_reduction_error_pct": 100 * float(np.mean(before)),
            "held_out_filtered_pct": 100 * float(np.mean(after)),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("stages", nargs="+")
    ap.add_argument("-C", "--workspace", default=None, help="default: the pipeline file's own, as `pipeline`")
    ap.add_argument("-f", "--file", default="pipeline.yaml")
    ap.add_argument("--bin-dir", default=None)
    ap.add_argument("--set", action="append", default=[], metavar="STAGE.KEY=VALUE")
    ap.add_argument("--split", default="validation")
    ap.add_argument("--cut-hz", type=float, default=51.0)
    ap.add_argument("--lags", type=int, default=15)
    a = ap.parse_args()
    sets = dict(kv.split("=", 1) for kv in a.set)
    pipe = pm.Pipeline(a.file, workspace=a.workspace, bin_dir=a.bin_dir, set=sets)
    for name, m in study(pipe, a.stages, a.split, a.cut_hz, a.lags).items():
        print(f"{name} ({a.split}, {m['samples']} samples)")
        print(f"  unloading rate: {m['reduction_error_pct']:.2f} % mean relative error")
        print(f"  deepest unloading {m['deepest_unloading_error_kn']:+.3f} kN, peak {m['peak_error_kn']:+.3f} kN (signed mean)")
        print(
            f"  error at or above {a.cut_hz:g} Hz taken out: {m['above_cut_removed_pct']:.2f} %; "
            f"below it taken out: {m['below_cut_removed_pct']:.2f} %"
        )
        print(
            f"  a linear filter of the excitations (+-{a.lags} steps) predicts {m['filter_variance_share_pct']:.1f} % "
            f"of the force error's variance on the odd ids; their unloading-rate error "
            f"{m['held_out_reduction_error_pct']:.2f} -> {m['held_out_filtered_pct']:.2f} %"
        )


if __name__ == "__main__":
    main()
