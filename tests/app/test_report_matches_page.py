"""Issue 45, point 6: the exported report says what the results page says — "validation", the 95 %
intervals, the flange's face as reactions — and its ± marks have a legend and strike no value."""

import numpy as np


def test_the_report_uses_the_pages_words_intervals_and_reactions(fitted, tmp_path):
    from pito_core.report import export_report
    from pito_core.calibration import validation_figures
    from pito_core.sim import simulate_calibration

    cal, ev = fitted
    main = simulate_calibration("face", 6, k=120, seed=4, faces=(1, 2, 3, 4, 5))  # SIMULATED
    figures = validation_figures(cal, main)
    path = export_report(tmp_path, cal, ev, {"simulated": True}, rmse={"reactions": 6, "kind": "validation"},
                         figures=figures)
    text = path.read_text()
    assert "## Validation RMSE per loaded face" in text and "Held-out RMSE" not in text
    assert "validation single-face samples" in text and "In use:" in text  # the page's model words too
    assert f"{figures.worst_force:.4f} N (face" in text and "95 %:" in text
    assert f"| 6 (reactions only) | {figures.reaction_force:.4f} |" in text and "reactions (face 6)" in text
    assert f"| 1 | {figures.rmse_force[0]:.4f} |" in text  # the page's per-face figures, not the held-out ones
    assert "± 95 %: half-width" in text
    # with the second mount's validation pass, face 6 has its own figure, as on the page (issue 45, point 2)
    both = validation_figures(cal, [main, simulate_calibration("frame_hole", 6, k=120, seed=5, faces=(6,))])
    text = export_report(tmp_path / "both", cal, ev, {"simulated": True}, figures=both,
                         rmse={"reactions": 6, "kind": "validation", "completed": (6,)}).read_text()
    assert f"| 6 | {both.rmse_force[5]:.4f} |" in text and "reactions only" not in text.split("## Validation")[1]
    assert "by loaded face — 1: " in text and "6: " in text.split("by loaded face")[1] and "(2nd mount)" in text


def test_value_labels_sit_above_the_interval_marks(fitted):
    from matplotlib.figure import Figure

    from pito_core.report import rmse_figure

    _, ev = fitted
    fig = rmse_figure(ev, Figure(figsize=(6.4, 2.8), dpi=100), dark=False, kind="validation")
    fig.canvas.draw() if hasattr(fig.canvas, "draw") else None
    for ax in fig.axes:
        marks = [c for c in ax.collections if c.get_label().startswith("± 95 %")]
        assert marks and ax.get_legend() is not None  # the marks have their legend
        ys = {round(float(x)): float(y) for x, y in marks[0].get_offsets()}
        for t in ax.texts:
            if t.get_text() == "n/a":
                continue
            x, y = t.xy
            assert y >= ys.get(round(x), -np.inf) - 1e-12, (t.get_text(), y, ys.get(round(x)))
        assert "validation" in ax.get_title()


def test_the_report_and_the_page_say_why_identification_scores_low(fitted, tmp_path):
    from pito_core.report import export_report, identification_note

    cal, ev = fitted
    ev.identified["force_norm"] = np.asarray(ev.identified["force_norm"], dtype=float) + 0.45  # crosstalk added
    note = identification_note(ev)
    assert note and "crosstalk" in note
    text = export_report(tmp_path, cal, ev, {"simulated": True}).read_text()
    assert note in text  # the words of the results page's line (app/wizard/results_page.py)
