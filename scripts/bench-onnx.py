#!/usr/bin/env python3
"""ONNX Runtime on one core against `predict` on one core (BENCHMARKS.md, "ONNX export").

    python3 scripts/bench-onnx.py MODEL.onnx MODEL_DIR CALIBRATION [--designs 2000]
                                  [--batch 16] [--rounds 3] [--bin-dir target/release]
                                  [--onnx-only]

Draws `--designs` designs uniformly over the file's training box (seed 7) under one profile
(the test's waviness, 0 to 600 m every 0.1 m), then alternates `--rounds` times: `predict
--indices --indices-only` of all of them with the calibration at 0.9 (RAYON_NUM_THREADS=1: one
core; its wall time, the process included), and in this process the numpy recipe of
examples/onnx/excitation.py for every design followed by ONNX Runtime on one thread
(`intra_op_num_threads = inter_op_num_threads = 1`) in batches of `--batch`, once asking for
every output and once for the indices, their intervals, verdicts and flags only. Prints each
round and the medians, and the ratio predict / ONNX Runtime. Needs numpy, pyarrow and
onnxruntime (the test environment).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
import onnxruntime as ort
import pyarrow as pa
import pyarrow.parquet as pq

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(root, "examples", "onnx"))
from excitation import excitation  # noqa: E402


def profile():
    x = np.arange(6000) * 0.1
    eta = (1.5e-3 * np.sin(x / 7.3) + 0.7e-3 * np.sin(x / 2.1 + 0.4) + 0.3e-3 * np.cos(x / 0.9)
           - 1e-3 * np.exp(-((x - 40.0) ** 2) / 4.0))
    return x, eta


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("onnx")
    ap.add_argument("model")
    ap.add_argument("calibration")
    ap.add_argument("--designs", type=int, default=2000)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--bin-dir", default=os.path.join(root, "target", "release"))
    ap.add_argument("--onnx-only", action="store_true", help="time ONNX Runtime alone (no predict)")
    a = ap.parse_args()
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    opts.inter_op_num_threads = 1
    session = ort.InferenceSession(a.onnx, opts, providers=["CPUExecutionProvider"])
    meta = json.loads(session.get_modelmeta().custom_metadata_map["pino.surrogate"])
    params, recipe = meta["inputs"]["parameters"], meta["inputs"]["excitation"]["recipe"]
    rng = np.random.default_rng(7)
    lo, hi = np.array(params["min"]), np.array(params["max"])
    x = lo + (hi - lo) * rng.random((a.designs, len(lo)))
    designs = [dict(zip(params["names"], row)) for row in x]
    px, pe = profile()
    points = {p["name"]: (px, pe) for p in recipe["profiles"] if p["kind"] == "points"}
    tmp = tempfile.mkdtemp()
    pq.write_table(pa.table({"x": px, "eta": pe}), os.path.join(tmp, "profile.parquet"))
    with open(os.path.join(tmp, "designs.json"), "w") as f:
        json.dump([{k: float(v) for k, v in d.items()} for d in designs], f)
    cmd = [os.path.join(a.bin_dir, "predict"), "--model", a.model, "--calibration", a.calibration,
           "--coverage", "0.9", "--params", os.path.join(tmp, "designs.json"),
           "--profile", os.path.join(tmp, "profile.parquet"), "--indices",
           os.path.join(tmp, "indices.parquet"), "--indices-only", "--batch", str(a.batch)]
    env = dict(os.environ, RAYON_NUM_THREADS="1", CANDLE_NUM_THREADS="1")
    few = [o.name for o in session.get_outputs()
           if o.name in ("indices", "indices_lo", "indices_hi", "verdicts", "extrapolated")]

    def onnx(outputs):
        t0 = time.perf_counter()
        for s in range(0, a.designs, a.batch):
            chunk = designs[s:s + a.batch]
            eta = np.stack([excitation(recipe, d, points) for d in chunk])
            session.run(outputs, {"parameters": x[s:s + a.batch], "excitation": eta})
        return time.perf_counter() - t0

    def predict():
        t0 = time.perf_counter()
        subprocess.run(cmd, env=env, check=True, capture_output=True)
        return time.perf_counter() - t0

    t_eta = time.perf_counter()
    for d in designs[: a.batch]:
        excitation(recipe, d, points)
    per_design_recipe = (time.perf_counter() - t_eta) / a.batch
    rows = {"predict": [], "onnx (all outputs)": [], "onnx (indices only)": []}
    for r in range(a.rounds):
        rows["predict"].append(0.0 if a.onnx_only else predict())
        rows["onnx (all outputs)"].append(onnx(None))
        rows["onnx (indices only)"].append(onnx(few))
        print(f"round {r + 1}: " + ", ".join(f"{k} {v[-1]:.2f} s" for k, v in rows.items()), flush=True)
    med = {k: statistics.median(v) for k, v in rows.items()}
    print(f"{a.designs} designs, batch {a.batch}, medians of {a.rounds}: "
          + ", ".join(f"{k} {v:.2f} s ({1e3 * v / a.designs:.2f} ms/design)" for k, v in med.items()))
    print(f"the numpy recipe alone: {1e3 * per_design_recipe:.2f} ms/design")
    for k in ("onnx (all outputs)", "onnx (indices only)"):
        if not a.onnx_only:
            print(f"predict / {k}: {med['predict'] / med[k]:.2f}")


if __name__ == "__main__":
    main()
