"""One session builder with one saturation rule (issue 22): ``session_from_arrays``."""

import numpy as np
import pytest

from pito_core.calibration import saturated_samples, session_from_arrays
from pito_core.frames import CUBE_ADC_LIMIT


def arrays(n=50, seed=0):
    rng = np.random.default_rng(seed)
    counts = rng.integers(-1000, 1000, (n, 36))
    ref = rng.standard_normal((n, 6))
    loaded = np.zeros((n, 6), bool)
    loaded[n // 2:, 0] = True
    return counts, ref, loaded, np.arange(n) / 1000.0


def test_saturated_and_non_finite_samples_are_dropped_and_counted():
    counts, ref, loaded, t = arrays()
    counts[3, 7] = CUBE_ADC_LIMIT
    counts[4, 0] = -CUBE_ADC_LIMIT - 5
    ref[5, 2] = np.nan
    sat_ref = np.zeros(50, bool)
    sat_ref[6] = True
    bad = saturated_samples(counts, ref, sat_ref)
    assert np.flatnonzero(bad).tolist() == [3, 4, 5, 6]
    s = session_from_arrays(counts, ref, loaded, t, T_core_ati=np.eye(4), flange="face", connected_face=6,
                            meta={"source": "test"}, reference_saturated=sat_ref)
    assert len(s) == 46 and s.meta["excluded_saturated_samples"] == 4 and s.meta["source"] == "test"
    assert np.allclose(s.time[:], np.delete(t, [3, 4, 5, 6]))


def test_errors_name_the_field():
    counts, ref, loaded, t = arrays()
    with pytest.raises(ValueError, match="reference"):
        session_from_arrays(counts, ref[:10], loaded, t, T_core_ati=np.eye(4), flange="face", connected_face=6)
    with pytest.raises(ValueError, match="every sample is saturated"):
        session_from_arrays(np.full((5, 36), CUBE_ADC_LIMIT), ref[:5], loaded[:5], T_core_ati=np.eye(4),
                            flange="face", connected_face=6)

