"""The exported ONNX file against the product's own answers (tests/interop/onnx.rs).

    check_onnx.py MODEL.onnx PROFILE.csv DESIGNS.json OUT_DIR [--no-intervals] [--routes FILE]

DESIGNS.json: a list of designs (dicts by parameter name). OUT_DIR holds what `predict` wrote
for them under the same profile: `histories-<level>.parquet` (`--out`) and
`indices-<level>.parquet` (`--indices`) for every level the file carries (or `histories.parquet`
and `indices.parquet` without intervals). The excitation is built by the recipe of
examples/onnx/excitation.py from PROFILE.csv (numpy only) and must equal `predict`'s to
round-off; the graph runs in ONNX Runtime on one thread. Both sides run the network in single
precision, with matrix kernels that sum in different orders: the network's outputs (every
channel that is not a central difference) must agree within 1e-5 of the channel's scale; a
channel that is a central difference of an output within what the difference makes of that
output's measured deviation (`1/dt` of it for a velocity, `4/dt^2` for an acceleration); an
index within 1e-5 of its value, or 20 times the relative deviation of the differenced channels
it reads. Everything after the network is double precision: every interval's and band's
half-width equals `predict`'s to 1e-9, verdicts and range flags exactly. The worst deviations
are printed. `--routes FILE` (JSON: `{"indices": {name: member}, "channels": {name: member}}`,
a surrogate's manifest): every index and channel of the file is answered by that member (its
key in the metadata's `members`).
"""

import json
import os
import sys

import numpy as np
import onnxruntime as ort
import pyarrow.parquet as pq

root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(root, "examples", "onnx"))
from excitation import excitation  # noqa: E402
from run import read_profiles  # noqa: E402

TOL = 1e-5
VERDICTS = {0: "pass", 1: "uncertain", 2: "fail"}
failures = []


def deviation(got, want, scale):
    """The largest |got - want| / scale (NaN where exactly one side is finite: a failure)."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    if not np.all(np.isfinite(got) == np.isfinite(want)):
        return np.inf
    both = np.isfinite(got)
    dev = np.abs(got - want)[both] / np.broadcast_to(np.maximum(scale, 1e-300), got.shape)[both]
    return float(dev.max()) if dev.size else 0.0


def check(what, dev, tol):
    if not dev <= tol:
        failures.append(f"{what}: deviation {dev:.3g} of its scale, allowed {tol:.3g}")
    return dev


def check_routes(meta, routes):
    """Each index and channel of the file answered by the member its route names."""
    keys = [m["key"] for m in meta["members"]]
    for kind in ("indices", "channels"):
        for q in meta[kind]:
            want = routes[kind].get(q["name"])
            if keys[q["member"]] != want:
                failures.append(f"{kind} {q['name']}: member {keys[q['member']]}, routed to {want}")


def main():
    model, profile, designs_file, out = sys.argv[1:5]
    intervals = "--no-intervals" not in sys.argv
    routes = None
    if "--routes" in sys.argv:
        routes = json.load(open(sys.argv[sys.argv.index("--routes") + 1]))
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    session = ort.InferenceSession(model, opts, providers=["CPUExecutionProvider"])
    meta = json.loads(session.get_modelmeta().custom_metadata_map["pino.surrogate"])
    params, recipe = meta["inputs"]["parameters"], meta["inputs"]["excitation"]["recipe"]
    designs = json.load(open(designs_file))
    profiles = read_profiles(profile, [p["name"] for p in recipe["profiles"] if p["kind"] == "points"])
    x = np.array([[d[n] for n in params["names"]] for d in designs])
    eta = np.stack([excitation(recipe, d, profiles) for d in designs])
    names = [o.name for o in session.get_outputs()]
    got = dict(zip(names, session.run(None, {"parameters": x, "excitation": eta})))
    levels = meta["intervals"]["levels"]
    assert bool(levels) == intervals, f"levels {levels}, intervals expected: {intervals}"
    assert ("channels_lo" in got) == intervals and ("indices_lo" in got) == (intervals and bool(meta["indices"]))
    b = len(designs)
    worst = {}
    dt = recipe["dt"]
    for l, level in enumerate(levels or [None]):
        tag = f"-{level}" if level is not None else ""
        h = pq.read_table(os.path.join(out, f"histories{tag}.parquet")).to_pydict()
        ix = pq.read_table(os.path.join(out, f"indices{tag}.parquet")).to_pydict()
        rows = got["channels"].shape[1]
        assert len(h["set"]) == b * rows, (len(h["set"]), b, rows)
        want = {ch["name"]: np.array(h[ch["name"]]).reshape(b, rows) for ch in meta["channels"]}
        # The network's outputs within TOL of their scale (single precision both ways); the
        # rates by central differences of them within what those differences make of the
        # outputs' measured deviation (2 / (2 dt) and 4 / dt^2 of it).
        rel = {}
        for c, ch in enumerate(meta["channels"]):
            scale = np.max(np.abs(want[ch["name"]]), axis=1, keepdims=True)
            g = got["channels"][:, :, c]
            if ch["derived"] is None:
                tol = TOL
            else:
                of = meta["channels"][[x["name"] for x in meta["channels"]].index(ch["derived"]["of"])]["name"]
                d = np.max(np.abs(got["channels"][:, :, [x["name"] for x in meta["channels"]].index(of)] - want[of]), axis=1)
                gain = 1 / dt if ch["derived"]["order"] == 1 else 4 / dt**2
                tol = max(TOL, float(np.max(1.001 * gain * d / scale[:, 0])))
            dev = check(ch["name"], deviation(g, want[ch["name"]], scale), tol)
            rel[ch["name"]] = dev
            worst["outputs" if ch["derived"] is None else "differences"] = max(
                worst.get("outputs" if ch["derived"] is None else "differences", 0), dev)
            if level is not None:
                # A band's half-width is the calibration's: equal to round-off.
                for end, sign in (("lo", -1), ("hi", 1)):
                    w = np.array(h[f"{ch['name']}_{end}"]).reshape(b, rows) - want[ch["name"]]
                    mine = got[f"channels_{end}"][:, l, :, c] - g
                    worst["bands"] = max(worst.get("bands", 0), check(
                        f"{ch['name']}_{end} at {level}", deviation(mine, w, np.abs(w).max()), 1e-9))
        # The excitation columns are exact inputs: the recipe's equal predict's.
        for j, e in enumerate(meta["inputs"]["excitation"]["names"]):
            w = np.array(h[e]).reshape(b, rows)
            worst["excitation"] = max(worst.get("excitation", 0), check(
                f"excitation {e}", deviation(eta[:, 1:-1, j], w, np.max(np.abs(w), axis=1, keepdims=True)), 1e-12))
        for i, q in enumerate(meta["indices"]):
            want_i = np.array(ix[q["name"]])
            # An index of differenced rates deviates as they do (peaks and RMS of sums with
            # the half length, the 1/10 power of Sperling's sum of cubes: a factor 20 covers
            # them); of outputs alone, within TOL.
            amplified = max([rel[r] for r in q["reads"] if r in rel and r not in
                             [c["name"] for c in meta["channels"] if c["derived"] is None]] or [0])
            tol = max(TOL, 20 * amplified)
            worst["indices"] = max(worst.get("indices", 0), check(
                q["name"], deviation(got["indices"][:, i], want_i, np.abs(want_i)), tol))
            if level is None:
                continue
            for end in ("lo", "hi"):
                w = np.array(ix[f"{q['name']}_{end}"]) - want_i
                mine = got[f"indices_{end}"][:, l, i] - got["indices"][:, i]
                worst["intervals"] = max(worst.get("intervals", 0), check(
                    f"{q['name']}_{end} at {level}", deviation(mine, w, np.abs(w)), 1e-9))
            if q["limit"] is not None:
                v = [VERDICTS[int(c)] for c in got["verdicts"][:, l, i]]
                if v != list(ix[f"{q['name']}_verdict"]):
                    failures.append(f"{q['name']} verdicts at {level}: {v} against {ix[q['name'] + '_verdict']}")
        flagged = [bool(s) for s in ix["outside_training_range"]]
        if [bool(v) for v in got["extrapolated"]] != flagged:
            failures.append(f"extrapolated {got['extrapolated']} against predict's {ix['outside_training_range']}")
        for k in range(b):
            named = {p.split("=")[0] for p in (ix["outside_training_range"][k] or "").split(",") if p}  # null inside
            mine = {params["names"][j] for j in np.flatnonzero(got["outside_training_range"][k])}
            if named != mine:
                failures.append(f"design {k}: outside {mine} against predict's {named}")
    if routes is not None:
        check_routes(meta, routes)
        used = sorted({meta["members"][q["member"]]["key"] for k in ("indices", "channels") for q in meta[k]})
        print(f"members {[m['key'] for m in meta['members']]}, answering: {used}")
    print(f"{os.path.basename(model)}: {b} designs, {len(meta['channels'])} channels, "
          f"{len(meta['indices'])} indices, levels {levels}; worst deviation over the scale: "
          + ", ".join(f"{k} {v:.2g}" for k, v in worst.items()))
    if failures:
        print("\n".join(failures[:400]))
        sys.exit(1)


if __name__ == "__main__":
    main()
