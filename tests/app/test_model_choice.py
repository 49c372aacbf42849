"""The results page's model section: words for the model choice, and the switch to linear."""

from app.wizard.model_choice import ModelChoiceBox, model_summary
from pito_core.calibration import ModelChoice


def test_model_section_says_which_and_why_and_switches(qtbot):
    choice = ModelChoice(name="poly", requested="auto", alpha=1e-4, reason="held-out error 0.2× the affine fit's",
                         cv_rmse={"linear": [0.5] * 3 + [0.004] * 3, "poly": [0.1] * 3 + [0.001] * 3})
    text = model_summary(choice)
    assert "polynomial correction" in text and "0.2×" in text
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
    assert "correction used on 2 of 6 output groups: face 2 forces, face 5 torques" in text
