"""``ModelChoice`` summaries shared by the CLI, the report and the results page."""

import numpy as np
import pytest

from pito_core.calibration import ModelChoice
from pito_core.cli._model import print_model


def test_cv_rms_splits_forces_and_torques():
    r = [3.0, 4.0, 0.0, 0.1, 0.1, 0.1] * 2
    choice = ModelChoice(name="poly", cv_rmse={"linear": r, "chosen": [1.0] * 12})
    out = choice.cv_rms()
    assert set(out) == {"linear", "chosen"}
    assert out["linear"][0] == pytest.approx(np.sqrt(25 / 3))
    assert out["linear"][1] == pytest.approx(0.1)
    assert out["chosen"] == pytest.approx((1.0, 1.0))


def test_corrected_follows_output_faces_order():
    rows = [None] * 6 + [0.1] * 6 + [None] * 3 + [0.2] * 3
    choice = ModelChoice(name="poly", row_alpha=rows)
    assert choice.corrected((6, 1, 3)) == [(1, "forces"), (1, "torques"), (3, "torques")]
    assert ModelChoice().corrected((1, 2)) == []


def test_print_model_names_the_mix(capsys):
    rows = [0.1] * 3 + [None] * 3
    choice = ModelChoice(name="poly", reason="wins", row_alpha=rows,
                         cv_rmse={"linear": [0.5] * 3 + [0.01] * 3, "poly": [0.2] * 3 + [0.02] * 3})
    print_model(choice, (4,))
    out = capsys.readouterr().out
    assert "correction used on 1 of 2 output groups: face 4 forces" in out
    assert "papers' linear fit" in out and "forces 0.5 N" in out and "torques 0.02 N·m" in out
