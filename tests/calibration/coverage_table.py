"""The coverage table of docs/calibration.md, "Uncertainty" (a script, not a test: minutes of CPU).

Nominal 95 % intervals against the TRUE face wrench of a later, re-tared session of a random
``gen.py`` cube (linear, or the nonlinear one of ``test_nonlinear.py``), per face and axis,
pooled over 16 calibrations (training draws) and, beside it, the range of single calibrations.
With a noisy reference the coefficients' error (and the estimate of the reference's own noise,
from a 300-sample tare) is one draw per calibration: a single calibration's coverage of one axis
scatters even where the intervals are right (``face_to_face``, linear cube, 3 %: 92.6–96.7 %),
so "nominal 95 %" is a statement over calibrations and samples, checked pooled over 16 of them
(16 × 6000 held-out samples per face and axis: σ ≈ 0.3 % there).

    PYTHONPATH=. python tests/calibration/coverage_table.py [methods] [lin,nl] [0,0.01,0.03] [linear,auto] [draws] [tare]

Beside the pooled figures, those of the samples where the face carries (the contact's face; 1/6 of
a face's samples or fewer, so the pooled figure is mostly its crosstalk's).

``tare``: samples at rest in each training session (default 300; the wizard's default tare is
2 s, 2000 samples at 1 kHz), from which the reference's noise is known.
"""

import itertools
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from gen import CASES, make_session, true_sensitivity  # noqa: E402
from test_nonlinear import nonlinear_response  # noqa: E402

from pito_core.calibration import calibrate  # noqa: E402

FACE = {"face_to_face": 3, "quasi_total": 2, "total": 6, "loaded_frame": 5, "unloaded_frame": 1}


def hits(cal, test):
    """Samples within the interval per face and axis (NaN where not measured), the same on the samples
    where the face carries (its own load: the contact's face), and the numbers of both."""
    loaded = test.loaded.any(axis=1)
    W, cov = cal.wrenches(test.counts[loaded], return_cov=True)
    e = W - test.true_face_wrenches[loaded]
    inside = np.abs(e) <= 1.959964 * np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))
    carries = np.abs(test.true_face_wrenches[loaded]).max(axis=2) > 0  # (n, 6)
    h = inside.sum(axis=0).astype(float)
    hc = (inside & carries[:, :, None]).sum(axis=0).astype(float)
    h[~(cal.coverage.faces & cal.has_output[:, None])] = np.nan
    hc[~(cal.coverage.faces & cal.has_output[:, None])] = np.nan
    return h, loaded.sum(), hc, carries.sum(axis=0)[:, None]


def sessions(method, K, kw, seed, k, noise):
    """The training (or held-out) sessions of a method: ``unloaded_frame`` takes its completing mount."""
    if method != "unloaded_frame":
        return [make_session(K, k=k, seed=seed, reference_noise=noise, **CASES[method], **kw)]
    return [make_session(K, flange="face", free_only=True, k=k, seed=seed, reference_noise=noise, **kw),
            make_session(K, flange="frame_hole", faces=[kw["connected_face"]], k=k, seed=seed + 500,
                         reference_noise=noise, **kw)]


def run(method, cube, noise, model, draws=16, seed=1, k=2000, kt=1000, tare=300):
    K = true_sensitivity(seed, coupling=0.05)
    kw = dict(connected_face=FACE[method], noise=2.0, counts_dtype=float, n_unloaded=tare)
    if cube == "nl":
        kw["response"] = nonlinear_response(seed, K, FACE[method], 0.08)
    tests = sessions(method, K, kw, seed + 1000, kt, 0.0)
    H, N, HC, NC, single = 0, 0, 0, 0, []
    for d in range(draws):
        cal = calibrate(sessions(method, K, kw, seed + 1 + 31 * d, k, noise), method, model=model)
        hh, nn = 0, 0
        for t in tests:
            h, n, hc, nc = hits(cal.tare(t.counts[~t.loaded.any(axis=1)]), t)
            hh, nn, HC, NC = hh + h, nn + n, HC + hc, NC + nc
        single.append(hh / nn)
        H, N = H + hh, N + nn
    with np.errstate(invalid="ignore"):
        return H / N, np.array(single), N, HC / NC


if __name__ == "__main__":
    args = sys.argv[1:] + [None] * 6
    methods = args[0].split(",") if args[0] else sorted(FACE)
    cubes = args[1].split(",") if args[1] else ["lin", "nl"]
    noises = [float(x) for x in args[2].split(",")] if args[2] else [0.0, 0.01, 0.03]
    models = args[3].split(",") if args[3] else ["linear", "auto"]
    for method, cube, noise, model in itertools.product(methods, cubes, noises, models):
        c, s, N, cc = run(method, cube, noise, model, draws=int(args[4] or 16), tare=int(args[5] or 300))
        v, sv, vc = c[np.isfinite(c)], s[np.isfinite(s)], cc[np.isfinite(cc)]
        out, out_c = (int(((x < 0.93) | (x > 0.97)).sum()) for x in (v, vc))
        print(f"{method:14s} {cube:3s} ref={noise:.4f} {model:6s} n={N:6d} pooled {v.min()*100:5.1f}-{v.max()*100:5.1f} "
              f"mean {v.mean()*100:5.1f} out of 93-97: {out:2d}/{v.size} | single {sv.min()*100:5.1f}-{sv.max()*100:5.1f} "
              f"| where the face carries {vc.min()*100:5.1f}-{vc.max()*100:5.1f} out {out_c:2d}/{vc.size}", flush=True)
