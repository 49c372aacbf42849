"""The model choice measured honestly: nested cross-validation of ``fit_sensor(model="auto")``.

Outer folds hold whole loading segments out; on each, ``fit_sensor`` chooses its model by its own
(inner) grouped cross-validation of the training segments alone, and is scored on the held-out
ones beside the plain affine least squares.
"""

import numpy as np
import pytest

from pito_core.calibration import fit_sensor
from test_sensor import FS, sensor_data

OUTER = 4


def _nested(counts, wrench, groups, truth):
    """``(outer RMSE ratio auto / linear, inner predicted ratios (OUTER,))`` (outputs scaled by full scale)."""
    e_auto = e_lin = 0.0
    inner = []
    for k in range(OUTER):
        test = groups % OUTER == k
        auto = fit_sensor(counts[~test], wrench[~test], groups[~test])
        lin = fit_sensor(counts[~test], wrench[~test], groups[~test], model="linear")
        e_auto += np.sum(((auto.predict(counts[test]) - truth[test]) / FS) ** 2)
        e_lin += np.sum(((lin.predict(counts[test]) - truth[test]) / FS) ** 2)
        s = auto.choice.cv_score
        inner.append(s["chosen"] / s["linear"])
    return np.sqrt(e_auto / e_lin), np.array(inner)


def test_nested_cv_the_choice_wins_where_the_sensor_is_nonlinear_and_its_inner_score_is_honest():
    c, w, g, truth = sensor_data(5, 6, 48, 40, sat=0.1)
    outer, inner = _nested(c, w, g, truth)
    assert outer <= 0.7, outer  # measured 0.58 (0.66 before the extension was chosen on held-out groups)
    # the inner cross-validation is optimistic (it chose on those folds, and the outer segments reach
    # beyond the training range, where the correction holds back): measured 0.47 against 0.58
    assert 0.6 * outer <= np.mean(inner) <= 1.1 * outer, (outer, inner)


@pytest.mark.parametrize("seed", [1])
def test_nested_cv_the_choice_never_loses_on_a_linear_sensor(seed):
    c, w, g, truth = sensor_data(seed, 8, 48, 40, drift=5.0, ref_noise=0.002)
    outer, _ = _nested(c, w, g, truth)
    assert outer <= 1.02, outer
