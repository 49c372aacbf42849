"""Why face identification scores what it does (issue 21 defect 9, issue 45): the breakdown of where single-face
identification fails matches a direct count on independent random forms (not the simulator)."""

from types import SimpleNamespace

import numpy as np

from pito_core.report import identification_breakdown, identification_note, identification_why


def _evaluation(seed=5, n=2000, crosstalk=0.3, threshold=0.5):
    rng = np.random.default_rng(seed)
    face = rng.integers(0, 6, n)
    true = np.zeros((n, 6), bool)
    true[np.arange(n), face] = True
    fn = np.abs(rng.normal(0.0, crosstalk, (n, 6)))  # unloaded faces: crosstalk only
    fn[true] = rng.uniform(0.2, 15.0, n)  # loaded faces: some below the threshold
    kind = np.where(rng.random(n) < 0.9, "single", "squeeze")
    return SimpleNamespace(identification={"force_threshold_N": threshold},
                           identified={"force_norm": fn, "true_loaded": true}, comparison={"kind": kind})


def test_breakdown_matches_a_direct_count():
    ev = _evaluation()
    fn, true, single = ev.identified["force_norm"], ev.identified["true_loaded"], ev.comparison["kind"] == "single"
    b = identification_breakdown(ev)
    assert b["n"] == single.sum()
    loaded = fn[single][true[single]]
    others = fn[single][~true[single]].reshape(-1, 5)
    assert np.isclose(b["missed"], (loaded <= 0.5).mean())
    assert np.isclose(b["phantom"], (others > 0.5).any(axis=1).mean())
    assert np.isclose(b["accuracy"][1.0], ((loaded > 0.5) & (others <= 0.5).all(axis=1)).mean())
    assert np.isclose(b["unloaded_median"], np.median(others))
    assert b["accuracy"][2.0] > b["accuracy"][1.0]  # crosstalk below 1 N: a higher threshold identifies more


def test_reaction_face_is_left_out_and_words_carry_the_numbers():
    ev = _evaluation()
    ev.identified["force_norm"][:, 5] = 9.0  # the flange's face carries reactions: never a phantom
    b = identification_breakdown(ev, reaction=6)
    assert b["phantom"] < 0.9
    text = identification_why(ev, reaction=6)
    assert f"{100 * b['phantom']:.1f} %" in text and "0.5 N" in text and "crosstalk" in text


def test_no_single_face_samples_gives_no_words():
    ev = _evaluation()
    ev.comparison["kind"][:] = "squeeze"
    assert identification_breakdown(ev) is None and identification_why(ev) == ""


def test_the_note_names_what_holds_the_figure_down():
    ev = _evaluation(crosstalk=0.4)
    b = identification_breakdown(ev)
    assert b["phantom"] > b["missed"] and b["accuracy"][1.0] < 0.95
    note = identification_note(ev)
    assert "crosstalk" in note and f"{100 * b['accuracy'][2.0]:.1f} %" in note and "at a 1 N threshold" in note
    quiet = _evaluation(crosstalk=0.01)
    quiet.identified["force_norm"][quiet.identified["true_loaded"]] = 5.0
    assert identification_note(quiet) == ""  # nothing to explain


def test_the_note_names_the_loaded_face_under_which_crosstalk_shows():
    """Issue 45: the crosstalk that holds the pooled figure down shows under one face's loads (the
    second mount's, on the simulator): the note and the paragraph name it, with both rates."""
    ev = _evaluation(crosstalk=0.05)
    fn, true = ev.identified["force_norm"], ev.identified["true_loaded"]
    six = true[:, 5]
    fn[six, 0] = 0.9  # under face 6's loads face 1 reads 0.9 N
    b = identification_breakdown(ev)
    single = ev.comparison["kind"] == "single"
    assert np.isclose(b["phantom_by_loaded"][5], 1.0) and np.nanmax(b["phantom_by_loaded"][:5]) < 0.01
    assert np.isclose(b["phantom"], (six & single).sum() / single.sum())
    note = identification_note(ev)
    assert "under face 6's loads 100 %" in note and note.startswith("crosstalk")
    assert "Under face 6's loads an unloaded face read above the threshold in 100.0 %" in identification_why(ev)
    ev.identified["evaluable"] = np.ones((len(six), 6), bool)  # per sample: which faces count (the mounts)
    ev.identified["evaluable"][:, 0] = False  # face 1 does not count: no crosstalk left
    assert identification_breakdown(ev)["phantom"] < 0.01 and identification_note(ev) == ""


def test_the_identification_figure_leaves_the_reactions_blank_and_says_each_loaded_face():
    """Issue 45: the face carrying the flange's reactions is not drawn as crosstalk; under each loaded face
    the share of its loads identified."""
    from matplotlib.figure import Figure

    from pito_core.report import identification_figure

    ev = _evaluation()
    n = len(ev.comparison["kind"])
    true = ev.identified["true_loaded"]
    ev.comparison["face"] = np.argmax(true, axis=1) + 1
    ev.identified["force_norm"][:, 5] = np.where(true[:, 5], 8.0, 9.0)  # face 6: reactions under the others' loads
    ev.identified["evaluable"] = np.ones((n, 6), bool)
    ev.identified["evaluable"][~true[:, 5], 5] = False  # scored only under its own loads (the second mount)
    ev.identification.update({"single": {"force": 0.9}, "by_loaded_face": {"force": [1.0] * 5 + [0.345]}})
    fig = identification_figure(ev, Figure(), dark=False)
    M = fig.axes[0].images[0].get_array()
    assert np.ma.getmaskarray(M)[5, :5].all() or np.isnan(np.ma.filled(M, np.nan)[5, :5]).all()
    assert np.isclose(M[5, 5], 8.0) and M[:5, :5].max() > 1.0
    labels = [t.get_text() for t in fig.axes[0].get_xticklabels()]
    assert labels[0] == "1\n100 %" and labels[5] == "6\n34 %"
