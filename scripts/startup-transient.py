#!/usr/bin/env python3
"""How long a description's response takes to forget the simulation's start: the measurement
behind a description's `indices_from` (docs/systems.md; BENCHMARKS.md, "Indices from the
settled response").

    python3 scripts/startup-transient.py DESCRIPTION [--designs 8] [--seed 1] [--duration 2]
        [--dt 1e-4] [--output-every 10] [--x0 20] [--lead 2] [--speed 'v_kmh / 3.6']
        [--start equilibrium] [--excitation-dx 0.1] [--excitation-length 600]
        [--bins 0,0.05,0.1,0.2,0.3,0.5,1,2]

Each design (the nominal one, then designs drawn uniformly in the description's ranges) runs
twice through the exact solver (`pino_mbd.System.simulate`) over the same generated profile:
once from `x0` (the run the pipeline stores) and once started `lead` seconds earlier along
the same profile, whose response at the same positions stands for the stationary one. The
moving frame's speed (`--speed`, an expression of the design's parameters) places the early
start a whole number of stored rows back, so both runs meet at the same stored positions.
For every stored column that is not a profile or a rate of one, the script prints, per time bin
after the start, the largest difference between the two runs over the designs, relative to the
column's standard deviation over the late run: where that falls under a few per cent, what the
indices read no longer depends on the start.

Needs numpy and polars (the Python package's own dependency)."""

from __future__ import annotations

import argparse
import math

import numpy as np
import polars as pl

import pino_mbd as pm


def designs(system: pm.System, n: int, seed: int) -> pl.DataFrame:
    """The nominal design, then `n - 1` drawn uniformly in the description's ranges."""
    p = system.parameters.filter(pl.col("name").is_in(system.design_parameters))
    rng = np.random.default_rng(seed)
    cols = {}
    for row in p.iter_rows(named=True):
        lo, hi = row["min"], row["max"]
        cols[row["name"]] = [row["nominal"], *rng.uniform(lo, hi, n - 1)]
    return pl.DataFrame(cols).with_row_index("sample_id").with_columns(pl.col("sample_id").cast(pl.Int64))


def differences(system: pm.System, table: pl.DataFrame, a: argparse.Namespace) -> dict[str, np.ndarray]:
    """Per column, per design, `|late - early|` on the late run's rows, over the column's std."""
    dt_row = a.dt * a.output_every
    kinds = system.columns
    skip = set(kinds.filter(pl.col("kind") == "excitation")["name"])
    out: dict[str, list[np.ndarray]] = {}
    for design in table.iter_rows(named=True):
        speed = eval(a.speed, {"__builtins__": {}, "math": math}, dict(design))  # noqa: S307
        rows = round(a.lead / dt_row)
        lead_m = speed * rows * dt_row
        one = pl.DataFrame({k: [v] for k, v in design.items()})
        run = dict(dt=a.dt, output_every=a.output_every, start=a.start, progress=False,
                   excitation={"seed": a.seed, "dx": a.excitation_dx, "length": a.excitation_length})
        late = system.simulate(one, duration=a.duration, x0=a.x0 + lead_m, **run)
        early = system.simulate(one, duration=a.duration + rows * dt_row, x0=a.x0, **run)
        early = early.slice(rows, late.height)
        for c in late.columns:
            if c in skip or c.startswith("eta_") or c in ("sample_id", "t"):
                continue
            x, y = late[c].to_numpy(), early[c].to_numpy()
            scale = float(np.std(x)) or 1.0
            out.setdefault(c, []).append(np.abs(x - y) / scale)
    return {c: np.array(v) for c, v in out.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("description")
    ap.add_argument("--designs", type=int, default=8)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--duration", type=float, default=2.0)
    ap.add_argument("--dt", type=float, default=1e-4)
    ap.add_argument("--output-every", type=int, default=10)
    ap.add_argument("--x0", type=float, default=20.0)
    ap.add_argument("--lead", type=float, default=2.0, help="s the early run starts before")
    ap.add_argument("--speed", default="v_kmh / 3.6", help="m/s, an expression of the design")
    ap.add_argument("--start", default="equilibrium")
    ap.add_argument("--excitation-dx", type=float, default=0.1)
    ap.add_argument("--excitation-length", type=float, default=600.0)
    ap.add_argument("--bins", default="0,0.05,0.1,0.2,0.3,0.5,1,2")
    a = ap.parse_args()
    system = pm.System.load(a.description)
    diff = differences(system, designs(system, a.designs, a.seed), a)
    edges = [float(b) for b in a.bins.split(",")]
    t = np.arange(next(iter(diff.values())).shape[1]) * a.dt * a.output_every
    print(f"{system.name}: max over {a.designs} designs of |late - early| / std(late), % (early start {a.lead} s before)")
    print("column".ljust(16) + "".join(f"{lo:g}-{hi:g} s".rjust(12) for lo, hi in zip(edges, edges[1:])))
    for c, d in diff.items():
        cells = []
        for lo, hi in zip(edges, edges[1:]):
            m = (t >= lo) & (t < hi)
            cells.append(f"{100 * d[:, m].max():.2f}".rjust(12) if m.any() else "-".rjust(12))
        print(c.ljust(16) + "".join(cells))


if __name__ == "__main__":
    main()
