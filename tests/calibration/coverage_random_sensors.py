"""Coverage of the true wrench on random linear sensors, not the cube's simulator (a script, not a test:
minutes of CPU); docs/calibration.md, "Uncertainty", "Not our simulator".

Four ``pito_core.sim.random_sensor`` sensors (condition 1–30), ``draws`` calibrations each (2000
single-face loads per face), scored on a later session re-tared on its own samples at rest: nominal 95 %
intervals per face and axis, pooled, and on the samples where the face carries (its own load).

    PYTHONPATH=. python tests/calibration/coverage_random_sensors.py REFERENCE_NOISE TARE DRAWS [linear|auto]
"""

import sys
import warnings

import numpy as np

from pito_core.calibration import calibrate
from pito_core.sim import random_sensor, random_sensor_session

CASES = [("total", "face"), ("unloaded_frame", "face"), ("face_to_face", "frame_hole"), ("loaded_frame", "frame_hole"),
         ("quasi_total", "frame")]


def run(method, flange, noise, tare, draws, model):
    """``(pooled (6, 6), where the face carries (6, 6))`` coverage, NaN where the calibration has no output."""
    hits = n = hits_c = n_c = 0
    for seed in (1, 2, 3, 4):
        sensor = random_sensor(seed, condition=(1.0, 30.0))
        faces = [1, 2, 3, 4, 5] if method == "unloaded_frame" else None
        test, truth = random_sensor_session(sensor, flange, 6, 1000, n_tare=1000, faces=faces, seed=900 + seed)
        ld = test.loaded.any(axis=1)
        for d in range(draws):
            train, _ = random_sensor_session(sensor, flange, 6, 2000, n_tare=tare, faces=faces, seed=10 + 37 * d + seed,
                                             reference_noise=noise)
            cal = calibrate(train, method, model=model).tare(test.counts[~ld])
            W, cov = cal.wrenches(test.counts[ld], return_cov=True)
            inside = np.abs(W - truth[ld]) <= 1.959964 * np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))
            carries = (np.abs(truth[ld]).max(axis=2) > 0)[:, :, None]
            hits, n = hits + inside.sum(axis=0), n + ld.sum()
            hits_c, n_c = hits_c + (inside & carries).sum(axis=0), n_c + carries.sum(axis=0)
    out = cal.has_output[:, None]
    return np.where(out, hits / n, np.nan), np.where(out, hits_c / np.maximum(n_c, 1), np.nan)


if __name__ == "__main__":
    noise, tare, draws = float(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
    model = sys.argv[4] if len(sys.argv) > 4 else "linear"
    warnings.simplefilter("ignore")  # a NoisyReferenceWarning above the tare's limits: the figures say it
    for method, flange in CASES:
        c, cc = run(method, flange, noise, tare, draws, model)
        v, vc = c[np.isfinite(c)], cc[np.isfinite(cc)]
        out, out_c = (int(((x < 0.93) | (x > 0.97)).sum()) for x in (v, vc))
        print(f"{method:14s} {flange:10s} ref={noise:.4f} tare={tare} {model:6s} pooled {100 * v.min():5.1f}-"
              f"{100 * v.max():5.1f} mean {100 * v.mean():5.1f} out {out}/{v.size} | where the face carries "
              f"{100 * vc.min():5.1f}-{100 * vc.max():5.1f} out {out_c}/{vc.size}", flush=True)
