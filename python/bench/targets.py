"""The issue's targets for pino_mbd (BENCHMARKS.md, "Python package"): not a test.

Usage: python python/bench/targets.py WORKSPACE BIN_DIR
WORKSPACE: a quarter-car pipeline workspace (configs/quarter-car.yaml as pipeline.yaml, the
binaries linked inside it as python/tests/conftest.py does); the model is trained there first
with the sizes of PINO_BENCH_SETS (default: the tests' TINY);
BIN_DIR: the stage binaries of the same build profile as the installed package.
Alternates the in-process call and the CLI, and prints medians.
"""

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import polars as pl

# The sizes the model was trained with: PINO_BENCH_SETS (JSON {"stage.key": value}), else the
# tests' TINY sizes (python/tests/conftest.py).
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from conftest import TINY  # noqa: E402

import os  # noqa: E402

SETS = json.loads(os.environ["PINO_BENCH_SETS"]) if os.environ.get("PINO_BENCH_SETS") else TINY

ws, bins = Path(sys.argv[1]), Path(sys.argv[2])
REPS = 5


def median_of(f, reps=REPS):
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


imp = statistics.median(
    float(subprocess.run([sys.executable, "-c", "import time; t=time.perf_counter(); import pino_mbd; print(time.perf_counter()-t)"],
                         capture_output=True, text=True, check=True).stdout)
    for _ in range(REPS)
)
print(f"import pino_mbd: {imp * 1e3:.0f} ms (median of {REPS} fresh interpreters)")

import pino_mbd  # noqa: E402

p = pino_mbd.Pipeline("pipeline.yaml", workspace=ws, set=SETS)
p.run("calibrate", jobs=2)
model_dir = p.dir("train[algorithm=5]", "model.safetensors")
cal = Path(p.dir("calibrate", "calibration.json")).parent
model = pino_mbd.Model.load(model_dir, calibration=cal)
one = {"k_s": [2.2e4]}
model.indices(one, excitation=7)
t1 = median_of(lambda: model.indices(one, excitation=7), reps=51)
print(f"model.indices, one design: {t1 * 1e3:.2f} ms (median of 51 calls)")

# 2000 random designs: in-process vs `predict --sweep ... --indices --indices-only`.
with tempfile.TemporaryDirectory() as d:
    d = Path(d)
    car = pino_mbd.System.load(ws / "systems" / "quarter-car.yaml")
    ranges = car.parameters.filter(pl.col("kind") == "sampled")
    sweep = {"random": {"seed": 3, "count": 2000, "ranges": {r["name"]: [r["min"], r["max"]] for r in ranges.iter_rows(named=True)}}}
    (d / "sweep.yaml").write_text(json.dumps(sweep))
    cmd = [str(bins / "predict"), "--model", model_dir, "--calibration", str(cal), "--seed", "7",
           "--sweep", str(d / "sweep.yaml"), "--indices", str(d / "ix.parquet"), "--indices-only"]
    subprocess.run(cmd, check=True, capture_output=True)
    designs = pl.read_parquet(d / "ix.parquet").select(ranges["name"].to_list())
    py_t, cli_t = [], []
    for _ in range(3):
        t0 = time.perf_counter(); subprocess.run(cmd, check=True, capture_output=True); cli_t.append(time.perf_counter() - t0)
        t0 = time.perf_counter(); model.indices(designs, excitation=7); py_t.append(time.perf_counter() - t0)
    print(f"2000 designs, indices: in-process {statistics.median(py_t):.3f} s, CLI predict {statistics.median(cli_t):.3f} s (medians of 3, alternated)")

# 1000 default designs through the solver: in-process vs the `simulate` stage (pipeline run
# -j 2: its two shards side by side, as the pipeline file runs it).
sets = {"sample-params.n_train": 997, "sample-params.n_validation": 1, "sample-params.n_test": 1,
        "sample-params.n_calibration": 1}  # 1000 samples in all
big = pino_mbd.Pipeline("pipeline.yaml", workspace=ws, set=sets)
big.run("simulate", jobs=2)
params = pl.read_parquet([f for f in big.show("sample-params") if f.endswith("params.parquet")])
irr = [f for f in big.show("irregularity") if f.endswith("irregularity.parquet")][0]
sim_dir = Path(big.dir("simulate", "simulation.parquet"))
c = json.loads((sim_dir / "run.json").read_text())["run"]
kw = {k: c[k] for k in ("duration", "dt", "output_every", "start", "x0", "startup_zero_fraction", "startup_ramp_fraction")}
py_t, st_t = [], []
for _ in range(3):
    t0 = time.perf_counter(); big.run("simulate", force=True, jobs=2); st_t.append(time.perf_counter() - t0)
    t0 = time.perf_counter(); car.simulate(params, excitation=irr, progress=False, **kw); py_t.append(time.perf_counter() - t0)
print(f"1000 designs x {c['duration']} s, simulate: in-process {statistics.median(py_t):.3f} s, stage (pipeline run simulate --force -j 2) {statistics.median(st_t):.3f} s (medians of 3, alternated)")
