"""The results page's model section: words for the model choice, and the switch to linear."""

from app.wizard.model_choice import ModelChoiceBox
from pito_core.report import model_summary
from pito_core.calibration import ModelChoice


def test_model_section_says_which_and_why_and_switches(qtbot):
    choice = ModelChoice(name="poly", requested="auto", alpha=1e-4, reason="held-out error 0.2× the affine fit's",
                         cv_rmse={"linear": [0.5] * 3 + [0.004] * 3, "poly": [0.1] * 3 + [0.001] * 3})
    text = model_summary(choice)
    assert "polynomial correction" in text and "0.2×" in text and "(in use)" in text
    assert "forces 0.500 N" in text and "torques 1.00 mN·m" in text
    box = ModelChoiceBox()
    qtbot.addWidget(box)
    box.show_choice(choice)
    assert box.requested == "auto"
    with qtbot.waitSignal(box.requested_changed) as sig:
        box.linear.setChecked(True)
    assert sig.args == ["linear"] and box.requested == "linear"


def test_model_section_names_the_corrected_groups():
    rows = [1e-3] * 3 + [None] * 3 + [None] * 6 + [None] * 3 + [2e-3] * 3  # faces 2, 4, 5 in that order
    choice = ModelChoice(name="poly", requested="auto", alpha=2e-3, reason="r", row_alpha=rows)
    text = model_summary(choice, (2, 4, 5))
    assert "polynomial correction on 2 of 6 output groups: face 2 forces, face 5 torques" in text


def test_the_model_in_use_is_named_beside_its_own_figure():
    """Issue 45, point 4: the correction won nowhere that matters (1.00×) and is worse everywhere:
    the text must not call the model in use "polynomial correction" beside the correction's 1.588 N."""
    import re

    rows = [None] * 36
    choice = ModelChoice(name="poly", requested="auto", alpha=1e-3, reason="held-out error 1.00× the affine fit's",
                         row_alpha=rows, cv_rmse={"linear": [0.728] * 3 + [0.01] * 3, "poly": [1.588] * 3 + [0.02] * 3,
                                                  "chosen": [0.728] * 3 + [0.01] * 3})
    text = model_summary(choice, (1, 2, 3, 4, 5, 6))
    assert "In use: the linear fit" in text and "polynomial correction on" not in text
    used = re.search(r"\(in use\)</b>: forces ([\d.]+) N", text)
    assert used and used.group(1) == "0.728", text
    assert re.search(r"on every output group: forces 1\.588 N", text)  # the candidate not used, named as such


def test_the_refused_correction_is_said_once():
    """Issue 45, point 4: after the validation pass refused the correction, the model text names the papers'
    linear fit once, then why (it read "the papers' linear fit (C = W S⁺) — the papers' linear fit: …")."""
    import numpy as np

    from pito_core.calibration import calibrate, confirm_model
    from pito_core.report import model_summary
    from pito_core.sim import VirtualCube, simulate_calibration

    cube = VirtualCube()
    train = simulate_calibration("frame_hole", 6, k=300, seed=1, model=cube)  # SIMULATED
    forced = calibrate(train, "loaded_frame", model="poly")
    fresh = simulate_calibration("frame_hole", 6, k=200, seed=9, model=cube, t0=100.0)
    cal, _ = confirm_model(forced, fresh)
    assert cal.correction is None  # the forced correction loses on fresh loads of this cube
    text = model_summary(cal.model, cal.output_faces)
    assert text.count("papers' linear fit") == 1 and "lost on the validation pass" in text
    assert np.isfinite(cal.matrix).all()
