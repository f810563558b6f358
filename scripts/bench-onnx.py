#!/usr/bin/env python3
"""ONNX Runtime on one core against `predict` on one core (BENCHMARKS.md, "ONNX export").

    python3 scripts/bench-onnx.py MODEL.onnx MODEL_DIR CALIBRATION [--designs 2000]
                                  [--batch 16] [--rounds 3] [--bin-dir target/release]
                                  [--onnx-only] [--profile]

Draws `--designs` designs uniformly over the file's training box (seed 7) under one profile
(the test's waviness, 0 to 600 m every 0.1 m), then alternates `--rounds` times: `predict
--indices --indices-only` of all of them with the calibration at 0.9 (RAYON_NUM_THREADS=1: one
core; its wall time, the process and the model's loading included), and in this process ONNX
Runtime: the session made (the file loaded and optimised), the profile's readers built once
(examples/onnx/excitation.py), then for every design the numpy recipe and the graph on one
thread in batches of `--batch`, once asking for every output and once for the indices, their
intervals, verdicts and flags only. Session options: CPU execution provider,
`intra_op_num_threads = inter_op_num_threads = 1`, sequential execution, graph optimisation
level `ORT_ENABLE_ALL` (ONNX Runtime's default; it fuses the GELU into one kernel). Prints
each round and the medians, and the ratio predict / ONNX Runtime.

`--profile`: instead, ONNX Runtime's profiler on one batch run 8 times; per operator type,
its share of the kernel time with each node counted at its fastest run (a floor that a busy
machine does not inflate), and the costliest nodes.

Needs numpy, pyarrow and onnxruntime (the test environment).
"""

import argparse
import collections
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
from excitation import excitation, readers  # noqa: E402


def profile():
    x = np.arange(6000) * 0.1
    eta = (1.5e-3 * np.sin(x / 7.3) + 0.7e-3 * np.sin(x / 2.1 + 0.4) + 0.3e-3 * np.cos(x / 0.9)
           - 1e-3 * np.exp(-((x - 40.0) ** 2) / 4.0))
    return x, eta


def session_options(profile=False):
    """One core, every graph optimisation."""
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    opts.inter_op_num_threads = 1
    opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    if profile:
        opts.enable_profiling = True
        opts.profile_file_prefix = os.path.join(tempfile.mkdtemp(), "ort")
    return opts


def profile_kernels(path, feeds, runs=8, top=int(os.environ.get("TOP", "15"))):
    """Per operator type, the share of the kernel time (each node at its fastest run)."""
    session = ort.InferenceSession(path, session_options(True), providers=["CPUExecutionProvider"])
    for _ in range(runs):
        session.run(None, feeds)
    events = json.load(open(session.end_profiling()))
    per, shapes = collections.defaultdict(list), {}
    for e in events:
        if e.get("cat") == "Node" and e["name"].endswith("_kernel_time"):
            key = (e["args"]["op_name"], e["name"][: -len("_kernel_time")])
            per[key].append(e["dur"])
            shapes[key] = e["args"].get("output_type_shape")
    floor = {k: min(v) for k, v in per.items()}
    total = sum(floor.values())
    batch = len(feeds["parameters"])
    print(f"{path}: {batch} designs a run, kernels at their fastest {total / 1e3:.1f} ms a run, "
          f"{total / 1e3 / batch:.2f} ms per design")
    by_op = collections.Counter()
    for (op, _), d in floor.items():
        by_op[op] += d
    for op, d in by_op.most_common():
        print(f"  {op:<14} {100 * d / total:5.1f} %  {d / 1e3:7.2f} ms")
    print("costliest nodes:")
    for (op, name), d in sorted(floor.items(), key=lambda kv: -kv[1])[:top]:
        print(f"  {op:<14} {name:<24} {d / 1e3:7.2f} ms  {shapes[(op, name)]}")


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
    ap.add_argument("--profile", action="store_true", help="ONNX Runtime's profiler on one batch")
    a = ap.parse_args()
    probe = ort.InferenceSession(a.onnx, session_options(), providers=["CPUExecutionProvider"])
    meta = json.loads(probe.get_modelmeta().custom_metadata_map["pino.surrogate"])
    params, recipe = meta["inputs"]["parameters"], meta["inputs"]["excitation"]["recipe"]
    rng = np.random.default_rng(7)
    lo, hi = np.array(params["min"]), np.array(params["max"])
    x = lo + (hi - lo) * rng.random((a.designs, len(lo)))
    designs = [dict(zip(params["names"], row)) for row in x]
    px, pe = profile()
    points = {p["name"]: (px, pe) for p in recipe["profiles"] if p["kind"] == "points"}
    if a.profile:
        built = readers(recipe, points)
        eta = np.stack([excitation(recipe, d, built) for d in designs[: a.batch]])
        profile_kernels(a.onnx, {"parameters": x[: a.batch], "excitation": eta})
        return
    tmp = tempfile.mkdtemp()
    pq.write_table(pa.table({"x": px, "eta": pe}), os.path.join(tmp, "profile.parquet"))
    with open(os.path.join(tmp, "designs.json"), "w") as f:
        json.dump([{k: float(v) for k, v in d.items()} for d in designs], f)
    cmd = [os.path.join(a.bin_dir, "predict"), "--model", a.model, "--calibration", a.calibration,
           "--coverage", "0.9", "--params", os.path.join(tmp, "designs.json"),
           "--profile", os.path.join(tmp, "profile.parquet"), "--indices",
           os.path.join(tmp, "indices.parquet"), "--indices-only", "--batch", str(a.batch)]
    env = dict(os.environ, RAYON_NUM_THREADS="1", CANDLE_NUM_THREADS="1")
    few = [o.name for o in probe.get_outputs()
           if o.name in ("indices", "indices_lo", "indices_hi", "verdicts", "extrapolated")]
    del probe
    loads = []

    def onnx(outputs):
        t0, c0 = time.perf_counter(), time.process_time()
        session = ort.InferenceSession(a.onnx, session_options(), providers=["CPUExecutionProvider"])
        loads.append(time.perf_counter() - t0)
        built = readers(recipe, points)
        for s in range(0, a.designs, a.batch):
            chunk = designs[s:s + a.batch]
            eta = np.stack([excitation(recipe, d, built) for d in chunk])
            session.run(outputs, {"parameters": x[s:s + a.batch], "excitation": eta})
        return time.perf_counter() - t0, time.process_time() - c0

    def predict():
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        if status != 0:
            sys.exit(f"predict failed: {p.stderr.read().decode()}")
        return wall, usage.ru_utime + usage.ru_stime

    built = readers(recipe, points)
    t_eta = time.perf_counter()
    for d in designs[: 4 * a.batch]:
        excitation(recipe, d, built)
    per_design_recipe = (time.perf_counter() - t_eta) / (4 * a.batch)
    rows = {"predict": [], "onnx (all outputs)": [], "onnx (indices only)": []}
    cpu = {k: [] for k in rows}
    for r in range(a.rounds):
        for k, f in (("predict", predict), ("onnx (all outputs)", lambda: onnx(None)),
                     ("onnx (indices only)", lambda: onnx(few))):
            wall, used = (0.0, 0.0) if (k == "predict" and a.onnx_only) else f()
            rows[k].append(wall)
            cpu[k].append(used)
        print(f"round {r + 1}: " + ", ".join(f"{k} {v[-1]:.2f} s ({cpu[k][-1]:.2f} s CPU)"
                                             for k, v in rows.items()), flush=True)
    med = {k: statistics.median(v) for k, v in rows.items()}
    med_cpu = {k: statistics.median(v) for k, v in cpu.items()}
    print(f"{a.designs} designs, batch {a.batch}, medians of {a.rounds} (wall; CPU time): "
          + ", ".join(f"{k} {v:.2f} s, {1e3 * v / a.designs:.2f} ms/design; "
                      f"{1e3 * med_cpu[k] / a.designs:.2f} ms/design CPU" for k, v in med.items()))
    print(f"of which the numpy recipe: {1e3 * per_design_recipe:.2f} ms/design; "
          f"the session's making: {statistics.median(loads):.2f} s")
    if not a.onnx_only:
        for k in ("onnx (all outputs)", "onnx (indices only)"):
            print(f"predict / {k}: {med['predict'] / med[k]:.2f} wall, "
                  f"{med_cpu['predict'] / med_cpu[k]:.2f} CPU time")

if __name__ == "__main__":
    main()
