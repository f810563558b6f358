"""Answers of an exported pino-mbd surrogate with numpy and ONNX Runtime alone.

    python examples/onnx/run.py model.onnx profile.csv [--level 0.9]

`model.onnx` is what `export` writes; `profile.csv` holds the track or road under the design:
columns `x` and `eta` (m), and `profile` naming each row's profile when the description has
several. Three designs are answered: the nominal one, the lower corner of the training box,
and the nominal one with its first parameter 20 % above its training range (flagged
`extrapolated`: its intervals carry no guarantee and its verdicts are never `pass`). For each,
every index with its interval at the level and its verdict against the index's limit.
"""

import argparse
import csv
import json
import os
import sys

import numpy as np
import onnxruntime as ort

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from excitation import excitation  # noqa: E402

VERDICTS = {-1: "-", 0: "pass", 1: "uncertain", 2: "fail"}


def read_profiles(path, names):
    """The points (x, eta) of each profile in `names` from a CSV file."""
    rows = list(csv.DictReader(open(path, newline="")))
    out = {}
    for name in names:
        mine = [r for r in rows if r.get("profile", name) == name]
        out[name] = (np.array([float(r["x"]) for r in mine]), np.array([float(r["eta"]) for r in mine]))
    return out


def designs(params):
    """Three designs by parameter name."""
    names, nominal = params["names"], params["nominal"]
    lower = dict(zip(names, params["min"]))
    outside = dict(zip(names, nominal))
    outside[names[0]] = params["max"][0] + 0.2 * (params["max"][0] - params["min"][0])
    return [("nominal", dict(zip(names, nominal))), ("lower corner", lower), (f"{names[0]} +20 % outside", outside)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("profile")
    ap.add_argument("--level", type=float, default=0.9)
    a = ap.parse_args()
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    session = ort.InferenceSession(a.model, opts, providers=["CPUExecutionProvider"])
    meta = json.loads(session.get_modelmeta().custom_metadata_map["pino.surrogate"])
    params = meta["inputs"]["parameters"]
    recipe = meta["inputs"]["excitation"]["recipe"]
    points = [p["name"] for p in recipe["profiles"] if p["kind"] == "points"]
    profiles = read_profiles(a.profile, points)
    chosen = designs(params)
    x = np.array([[d[n] for n in params["names"]] for _, d in chosen])
    eta = np.stack([excitation(recipe, d, profiles) for _, d in chosen])
    outputs = [o.name for o in session.get_outputs()]
    got = dict(zip(outputs, session.run(None, {"parameters": x, "excitation": eta})))
    levels = meta["intervals"]["levels"]
    print(f"system `{meta['system']['name']}` (description {meta['system']['hash'][:12]}), "
          f"{len(meta['channels'])} channels, {len(meta['indices'])} indices")
    if not levels:
        print(f"no intervals: {meta['intervals']['why']}")
    elif a.level not in levels:
        sys.exit(f"--level {a.level}: the file carries {levels}")
    for k, (label, _) in enumerate(chosen):
        flag = " (extrapolated: no guarantee)" if got["extrapolated"][k] else ""
        print(f"\n{label}{flag}")
        for i, ix in enumerate(meta["indices"]):
            line = f"  {ix['name']:<32} {got['indices'][k, i]:12.5g} {ix['unit']:<6}"
            if levels:
                l = levels.index(a.level)
                lo, hi = got["indices_lo"][k, l, i], got["indices_hi"][k, l, i]
                verdict = VERDICTS[int(got["verdicts"][k, l, i])]
                line += f" {a.level:.0%} [{lo:.5g}, {hi:.5g}]  {verdict}"
            print(line)


if __name__ == "__main__":
    main()
