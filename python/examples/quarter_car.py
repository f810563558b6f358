# The worked example of docs/python.md (included there verbatim; python/tests runs it).
# Usage, from the repository root after `pipeline -f configs/quarter-car.yaml run calibrate`:
#   python python/examples/quarter_car.py MODEL_DIR CALIBRATION_DIR OUT_DIR
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import polars as pl
from SALib.analyze import sobol
from SALib.sample import sobol as saltelli

import pino_mbd

model_dir, calibration_dir, out = sys.argv[1], sys.argv[2], Path(sys.argv[3])
out.mkdir(parents=True, exist_ok=True)

# 1. Describe: the quarter car's parameters (units, nominal values, ranges) and columns.
car = pino_mbd.System.load("systems/quarter-car.yaml")
print(car.parameters.select("name", "unit", "kind", "nominal", "min", "max"))
print(car.columns.filter(pl.col("kind") == "solution"))

# 2. Simulate 100 designs with the exact solver (all cores, GIL released): suspension
#    stiffness k_s (N/m) and damping c_s (N s/m) on a grid, each on its own class C road.
k_s, c_s = np.meshgrid(np.linspace(1.6e4, 2.8e4, 10), np.linspace(1.0e3, 2.0e3, 10))
designs = pl.DataFrame({"sample_id": np.arange(100), "k_s": k_s.ravel(), "c_s": c_s.ravel()})
sim = car.simulate(
    designs,
    excitation={"seed": 1, "dx": 0.1, "length": 200.0},  # profiles as the irregularity stage makes them
    duration=2.0, dt=2.0e-4, output_every=10, x0=5.0,    # s, s, steps per row, m
)
rms = sim.group_by("sample_id").agg(pl.col("z_s_a").pow(2).mean().sqrt().alias("rms_z_s_a")).sort("sample_id")
print(rms.join(designs, on="sample_id").sort("rms_z_s_a").head(3))  # the smoothest rides (m/s^2)

# 3. Load the trained surrogate with its calibration; predict one design's time histories.
model = pino_mbd.Model.load(model_dir, calibration=calibration_dir)
p = model.predict({"k_s": [2.2e4], "c_s": [1.5e3]}, excitation=7)

# 4. Plot the predicted body displacement with its calibrated 90 % band to a PNG.
fig, ax = plt.subplots(figsize=(7, 3))
ax.fill_between(p["t"], p["z_s_lo"] * 1e3, p["z_s_hi"] * 1e3, alpha=0.3, label="90 % band")
ax.plot(p["t"], p["z_s"] * 1e3, label="surrogate")
ax.set_xlabel("t (s)")
ax.set_ylabel("z_s (mm, down)")
ax.legend()
fig.savefig(out / "z_s.png", dpi=100)

# 5. Sobol sensitivity (SALib) of the ride comfort index over the training ranges, through
#    model.indices: one row per design with intervals and verdicts.
ranges = car.parameters.filter(pl.col("kind") == "sampled")
names = ranges["name"].to_list()
problem = {
    "num_vars": len(names),
    "names": np.asarray(names),  # an array: SALib 1.5.1's pd.unique needs one under pandas 3
    "bounds": ranges.select("min", "max").rows(),
}
x = saltelli.sample(problem, 64, calc_second_order=False, seed=1)
ix = model.indices(pl.DataFrame(x, schema=names, orient="row"), excitation=7)
s = sobol.analyze(problem, ix["sprung_rms_acceleration"].to_numpy(), calc_second_order=False, seed=1)
print(pl.DataFrame({"parameter": names, "S1": s["S1"], "ST": s["ST"]}).sort("ST", descending=True))
print(ix["verdict"].value_counts())
