"""The excitation input of an exported pino-mbd surrogate, built with numpy alone.

`excitation(recipe, design, profiles)` follows the recipe the exporter writes into the file's
metadata (`pino.surrogate` -> `inputs.excitation.recipe`) exactly as `predict` builds the
excitation (docs/export.md):

    t_n   = t0 + n dt                               n = 0 .. points - 1
    x_e   = (x0 + v t) + o_e                        v, o_e affine in the design's parameters
    r(t)  = 0 before profile_on, (t - profile_on) / ramp during the ramp, 1 after
    eta_e = r eta(x_e)                              a `profile` column (m), 0 while r = 0
    rate  = r v eta'(x_e) + r' eta(x_e)             a `rate` column (m/s)

with eta the profile the column's element reads: its points read linearly or by the
not-a-knot cubic spline, clamped beyond the ends (slope 0 there), or a harmonic.
"""

import numpy as np


def affine(form, design):
    """`constant + sum c_j p_j` of an affine form over the design's parameters (a dict)."""
    return form["constant"] + sum(c * design[name] for name, c in form["per_parameter"].items())


def spline_cells(x, eta):
    """Per cell n, (s_n, c2_n, c3_n) of eta_n + s_n t + c2_n t^2 + c3_n t^3: the not-a-knot
    cubic spline through at least 4 points (the slopes solve one tridiagonal system)."""
    n = len(x)
    h = np.diff(x)
    d = np.diff(eta) / h
    lower, diag, upper, rhs = (np.zeros(n) for _ in range(4))
    diag[0], upper[0] = h[1], h[0] + h[1]
    rhs[0] = ((h[0] + 2 * (h[0] + h[1])) * h[1] * d[0] + h[0] ** 2 * d[1]) / (h[0] + h[1])
    lower[1:-1], diag[1:-1], upper[1:-1] = h[1:], 2 * (h[:-1] + h[1:]), h[:-1]
    rhs[1:-1] = 3 * (h[1:] * d[:-1] + h[:-1] * d[1:])
    m = n - 2
    lower[-1], diag[-1] = h[m] + h[m - 1], h[m - 1]
    rhs[-1] = (h[m] ** 2 * d[m - 1] + (2 * (h[m - 1] + h[m]) + h[m]) * h[m - 1] * d[m]) / (h[m - 1] + h[m])
    for i in range(1, n):
        f = lower[i] / diag[i - 1]
        diag[i] -= f * upper[i - 1]
        rhs[i] -= f * rhs[i - 1]
    s = np.zeros(n)
    s[-1] = rhs[-1] / diag[-1]
    for i in range(n - 2, -1, -1):
        s[i] = (rhs[i] - upper[i] * s[i + 1]) / diag[i]
    c2 = (3 * d - 2 * s[:-1] - s[1:]) / h
    c3 = (s[:-1] + s[1:] - 2 * d) / (h * h)
    return s[:-1], c2, c3


def profile_reader(spec, points):
    """(eta, slope) functions of one profile: `spec` its recipe entry, `points` its (x, eta)."""
    if spec["kind"] == "harmonic":
        a, wl, phi = spec["amplitude"], spec["wavelength"], spec["phase"]
        k = 2 * np.pi / wl
        return (lambda x: a * np.sin(2 * np.pi * x / wl + phi)), (lambda x: a * k * np.cos(k * x + phi))
    px, pe = (np.asarray(v, dtype=np.float64) for v in points)
    cell = lambda x: np.clip(np.searchsorted(px, x, side="right"), 1, len(px) - 1)
    inside = lambda x: (x >= px[0]) & (x <= px[-1])
    if spec["interpolation"] == "cubic":
        s, c2, c3 = spline_cells(px, pe)

        def at(x):
            i = cell(x) - 1
            t = np.clip(x, px[i], px[i + 1]) - px[i]
            return pe[i] + t * (s[i] + t * (c2[i] + t * c3[i]))

        def slope(x):
            i = cell(x) - 1
            t = x - px[i]
            return np.where(inside(x), s[i] + t * (2 * c2[i] + t * 3 * c3[i]), 0.0)

        return at, slope

    def at(x):
        i = cell(x)
        w = np.clip((x - px[i - 1]) / (px[i] - px[i - 1]), 0.0, 1.0)
        return pe[i - 1] + w * (pe[i] - pe[i - 1])

    def slope(x):
        i = cell(x)
        return np.where(inside(x), (pe[i] - pe[i - 1]) / (px[i] - px[i - 1]), 0.0)

    return at, slope


def excitation(recipe, design, profiles):
    """The excitation `[points, columns]` of one design (a dict of its parameters by name);
    `profiles` maps each generated profile's name to its points (x, eta) in metres."""
    t = recipe["t0"] + recipe["dt"] * np.arange(recipe["points"])
    on, width = recipe["profile_on"], recipe["ramp"]
    if width > 0:
        ramp = np.where(t < on, 0.0, np.where(t >= on + width, 1.0, (t - on) / width))
        ramp_rate = np.where((t >= on) & (t < on + width), 1.0 / width, 0.0)
    else:
        ramp = np.where(t < on, 0.0, 1.0)
        ramp_rate = np.zeros_like(t)
    speed = affine(recipe["speed"], design)
    readers = {p["name"]: profile_reader(p, profiles.get(p["name"])) for p in recipe["profiles"]}
    out = np.zeros((len(t), len(recipe["columns"])))
    for j, col in enumerate(recipe["columns"]):
        x = (recipe["x0"] + speed * t) + affine(col["offset"], design)
        at, slope = readers[col["profile"]]
        if col["kind"] == "profile":
            out[:, j] = np.where(ramp > 0, ramp * at(x), 0.0)
        else:
            out[:, j] = ramp * speed * slope(x) + ramp_rate * at(x)
    return out
