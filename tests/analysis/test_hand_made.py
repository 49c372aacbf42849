"""Trials, phases and metrics of hand-made contact arrays with analytic answers (not the simulator).

Object upside down on the table on face 5 (gravity +z of the core frame), fingers on faces 2
and 4 (the simulator uses 5 → 6, 1 and 3), 500 Hz with jittered sample times.
"""

from dataclasses import replace

import numpy as np
import pytest

from pito_core.analysis import AnalysisSettings, analyze_contacts, grasp_series, segment_trials, trial_figure
from pito_core.contact import ContactEstimate

H = 0.028  # contact plane, m from the core centre
MASS = 3.0 / 9.81  # kg: the fingers carry 3 N


def hand_made(flag=True, rng_seed=0):
    """``(time (n,) s, ContactEstimate (n, 6, …) core frame)``."""
    rng = np.random.default_rng(rng_seed)
    t = np.arange(0, 4.0, 0.002) + rng.uniform(0, 5e-4, 2000)
    n = t.size
    point = np.full((n, 6, 3), np.nan)
    normal = np.zeros((n, 6, 3))
    force = np.zeros((n, 6, 3))
    valid = np.zeros((n, 6), bool)
    fingers = (t >= 0.4) & (t < 3.5)
    base = (t < 1.0) | (t >= 3.0)
    air = ~base
    x = 0.006 * np.clip((t - 1.5) / 1.0, 0, 1)  # the face-2 finger slides 6 mm along x
    squeeze = np.where(air, 3.0, 2.0)
    lift = np.where(air, 1.5, 0.0)  # each finger carries 1.5 N against gravity (+z) while in the air
    for i, sign, px in ((1, 1.0, x), (3, -1.0, np.zeros(n))):
        point[fingers, i] = np.stack([px, np.full(n, sign * H), np.zeros(n)], axis=1)[fingers]
        normal[:, i] = [0, sign, 0]
        force[fingers, i] = np.stack([np.zeros(n), -sign * squeeze, -lift], axis=1)[fingers]
        valid[:, i] = fingers
    point[base, 4] = [0.0, 0.0, H]
    normal[:, 4] = [0, 0, 1]
    force[base, 4] = [0, 0, -3.0]
    valid[:, 4] = base
    single = np.ones((n, 6), bool)
    single[(t >= 1.8) & (t < 2.1), 3] = False  # face 4: two fingers for 0.3 s of the hold
    return t, ContactEstimate(point, normal, force, np.zeros((n, 6)), valid, single_contact=single if flag else None,
                              frame="core")


SETTINGS = AnalysisSettings(base_face=5, lift_phase=0.3, replace_phase=0.3)


def test_phases_and_metrics_are_the_analytic_values():
    time, c = hand_made()
    a = analyze_contacts(time, c, SETTINGS, mass=MASS)
    (tr,) = a.trials
    dt = 0.0025
    assert tr.start == pytest.approx(0.4, abs=dt) and tr.stop == pytest.approx(3.5, abs=dt)
    assert tr.lift_off == pytest.approx(1.0, abs=dt) and tr.touch_down == pytest.approx(3.0, abs=dt)
    assert list(tr.phases) == ["load", "lift", "hold", "replace", "release"]
    assert tr.phases["hold"] == pytest.approx((1.3, 2.7), abs=dt)
    assert tr.onset == pytest.approx({2: 0.4, 4: 0.4, 5: 0.4}, abs=dt)  # the base: in contact when the trial starts
    hold = a.phases.set_index("phase").loc["hold"]
    assert hold["grip_force_N"] == pytest.approx(6.0) and hold["load_force_N"] == pytest.approx(3.0)
    assert hold["grip_load_ratio"] == pytest.approx(2.0) and hold["support_force_N"] == 0
    # internal: the squeeze's component along the line between the fingertips (the slide tilts it by θ)
    m = (time >= 1.3) & (time < 2.7)
    cos = 2 * H / np.hypot(np.clip((time[m] - 1.5) / 1.0, 0, 1) * 0.006, 2 * H)
    assert hold["internal_force_N"] == pytest.approx(np.mean(2 * 3.0 * cos), rel=1e-3)
    assert hold["manipulation_force_N"] == pytest.approx(np.mean(2 * np.hypot(1.5, 3.0 * np.sqrt(1 - cos**2))),
                                                         rel=1e-3)
    assert hold["net_force_N"] == pytest.approx(3.0) and hold["residual_force_N"] == pytest.approx(0, abs=1e-9)
    # ‖M‖ = |x|·√(1.5² + 3²) about the centre; mean |x| over the hold = 3 mm
    assert hold["residual_moment_Nmm"] == pytest.approx(3.0 * np.hypot(1.5, 3.0), rel=0.01)
    load = a.phases.set_index("phase").loc["load"]
    assert load["grip_force_N"] == pytest.approx(4.0) and load["load_force_N"] == pytest.approx(0, abs=1e-12)
    assert load["support_force_N"] == pytest.approx(3.0 * 0.6 / 0.6)
    p = a.patches[a.patches["phase"] == "hold"].assign(face=lambda d: d["face"].astype(int)).set_index("face")
    assert p.loc[2, "path_length_mm"] == pytest.approx(6.0, abs=0.1)
    x = np.clip((np.arange(1.3, 2.7, 1e-4) - 1.5) / 1.0, 0, 1) * 6.0
    assert p.loc[2, "spread_mm"] == pytest.approx(np.std(x), abs=0.05)
    assert p.loc[4, "path_length_mm"] == pytest.approx(0, abs=1e-9)
    assert p.loc[2, "share_pct"] == pytest.approx(50) and p.loc[4, "share_pct"] == pytest.approx(50)
    assert set(a.patches["role"].astype(str)) == {"finger", "base"}


def test_a_phase_with_other_than_single_contacts_is_marked_not_averaged_in():
    a = analyze_contacts(*hand_made(), SETTINGS, mass=MASS)
    ph = a.phases.set_index("phase")
    assert ph.loc["hold", "plausible"] == False  # noqa: E712 (nullable boolean)
    assert ph.loc["hold", "single_contact_frac"] == pytest.approx(1 - 0.3 / 1.4, abs=0.01)
    assert ph.drop("hold")["plausible"].all()
    p = a.patches[(a.patches["phase"] == "hold")].assign(face=lambda d: d["face"].astype(int)).set_index("face")
    assert p.loc[4, "plausible"] == False and p.loc[2, "plausible"] == True  # noqa: E712
    fig = trial_figure(a, a.trials[0])
    assert "not single contacts" in fig._suptitle.get_text() and "hold" in fig._suptitle.get_text()
    unflagged = analyze_contacts(*hand_made(flag=False), SETTINGS, mass=MASS)
    assert unflagged.phases["plausible"].isna().all() and unflagged.phases["single_contact_frac"].isna().all()
    assert "not single" not in trial_figure(unflagged, unflagged.trials[0])._suptitle.get_text()


def test_segmentation_debounces_and_needs_two_fingers():
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.0008, 0.0012, 8000))
    fn = np.zeros((t.size, 6))
    fn[(t > 1) & (t < 3), 0] = 2.0
    fn[(t > 1.2) & (t < 2.8), 2] = 2.0
    fn[(t > 2.0) & (t < 2.02)] = 0.0  # a 20 ms drop-out of both: ignored (shorter than min_contact)
    fn[(t > 4) & (t < 6), 0] = 2.0  # one finger only: no trial
    fn[np.ix_((t > 6.5) & (t < 6.53), [0, 2])] = 2.0  # a 30 ms blip of two fingers: no trial
    trials = segment_trials(t, fn, AnalysisSettings(base_face=0))
    assert len(trials) == 1
    assert trials[0].phases["hold"] == pytest.approx((1.0, 3.0), abs=0.002)
    assert trials[0].onset == pytest.approx({1: 1.0, 3: 1.2}, abs=0.002)


@pytest.mark.parametrize("field, value", [("contact_force", -1.0), ("base_face", 7), ("min_fingers", 0),
                                          ("mass", 0.0), ("single_contact_min", 1.5), ("lift_phase", float("nan"))])
def test_settings_name_the_bad_field(field, value):
    with pytest.raises(ValueError, match=field):
        AnalysisSettings(**{field: value})


def test_bad_contacts_name_the_field():
    time, c = hand_made()
    with pytest.raises(ValueError, match="contacts.force: expected shape"):
        analyze_contacts(time, replace(c, force=c.force[:, :5]), SETTINGS)
    with pytest.raises(ValueError, match="contacts.single_contact: expected shape"):
        grasp_series(time, replace(c, single_contact=c.single_contact[1:]), SETTINGS)
    with pytest.raises(ValueError, match="time: expected strictly increasing"):
        analyze_contacts(time[::-1], c, SETTINGS)
    with pytest.raises(ValueError, match="contacts.frame: expected 'core'"):  # one patch's face-frame contacts
        analyze_contacts(time, replace(c, frame="face"), SETTINGS)
    with pytest.raises(TypeError, match="contacts: expected a ContactEstimate"):
        analyze_contacts(time, {"point": c.point}, SETTINGS)


def test_contacts_in_other_dtypes_give_the_same_tables():
    # int forces and 0/1 validity (e.g. read back from a table) are cast, not rejected; the record is not modified
    time, c = hand_made()
    ints = replace(c, force=np.round(c.force).astype(np.int64), valid=c.valid.astype(np.uint8),
                   single_contact=c.single_contact.astype(np.int8))
    floats = replace(c, force=np.round(c.force))
    a, b = analyze_contacts(time, ints, SETTINGS, mass=MASS), analyze_contacts(time, floats, SETTINGS, mass=MASS)
    assert ints.force.dtype == np.int64 and ints.valid.dtype == np.uint8
    assert a.phases.equals(b.phases) and a.patches.equals(b.patches) and len(a.trials) == 1
