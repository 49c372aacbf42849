"""A SIMULATED lift-hold-replace recording through the one pipeline: every metric against the task's truth."""

import numpy as np
import pytest

from pito_core.analysis import analyze_contacts, analyze_recording
from pito_core.contact import ContactEstimate

#: Largest |error| allowed per metric (units of the column): the solver's noise on the simulated cube.
PHASE_TOL = {"start_s": 0.005, "stop_s": 0.005, "duration_s": 0.005, "grip_force_N": 0.05, "load_force_N": 0.05,
             "support_force_N": 0.02, "net_force_N": 0.03, "manipulation_force_N": 0.03, "internal_force_N": 0.05,
             "residual_force_N": 0.03, "residual_moment_Nmm": 1.5}  # N·mm: ~0.05 N of noise at 28 mm
PATCH_TOL = {"onset_s": 0.005, "contact_frac": 0.005, "normal_force_N": 0.03, "tangential_force_N": 0.03,
             "share_pct": 0.3, "manipulation_force_N": 0.03, "internal_force_N": 0.03, "path_length_mm": 0.4,
             "spread_mm": 0.05}


@pytest.fixture(scope="module")
def analysed(lift_recording):
    path, task, truth = lift_recording
    a = analyze_recording(path)
    c = ContactEstimate(truth.point, truth.normal, truth.force, truth.torsion, truth.valid,
                        single_contact=np.ones(truth.valid.shape, bool), frame="core")
    b = analyze_contacts(truth.time, c, cog=task.cog, mass=task.mass)
    return a, b, task


def test_trials_and_phases_match_the_task(analysed):
    a, b, task = analysed
    assert len(a.trials) == len(b.trials) == task.n_trials
    for tr, k in zip(a.trials, range(task.n_trials)):
        design = task.trial_times(k)
        assert list(tr.phases) == ["load", "lift", "hold", "replace", "release"]
        # the table's normal force crosses the contact threshold inside the designed load transfer
        assert design["load"][0] < tr.lift_off <= design["lift"][0]
        assert design["replace"][1] <= tr.touch_down < design["settle"][1]
        assert design["touch"][0] < tr.start < design["touch"][1] and design["release"][0] < tr.stop < design["release"][1]
    assert a.simulated and not b.simulated


def test_every_metric_matches_the_truth(analysed):
    a, b, task = analysed
    assert len(a.phases) == len(b.phases) and len(a.patches) == len(b.patches)
    for df_a, df_b, tol in ((a.phases, b.phases, PHASE_TOL), (a.patches, b.patches, PATCH_TOL)):
        for col, limit in tol.items():
            err = np.abs(df_a[col].to_numpy(float) - df_b[col].to_numpy(float))
            assert np.nanmax(err) < limit, (col, np.nanmax(err))
    ratio = np.abs(a.phases["grip_load_ratio"] / b.phases["grip_load_ratio"] - 1)
    assert ratio.max() < 0.05
    assert a.phases["plausible"].all() and (a.phases["single_contact_frac"] > 0.99).all()


def test_analytic_values_of_the_task(analysed):
    a, _, task = analysed
    hold = a.phases[a.phases["phase"] == "hold"]
    # two fingers: the internal force is the squeeze on each, twice the trial's grip setting
    np.testing.assert_allclose(hold["internal_force_N"], 2 * task.grips, rtol=0.01)
    np.testing.assert_allclose(hold["support_force_N"], 0, atol=1e-12)
    index = a.patches[(a.patches["phase"] == "hold") & (a.patches["face"] == 1)]
    np.testing.assert_allclose(index["path_length_mm"], 1e3 * task.slides, atol=0.3)
    np.testing.assert_allclose(a.patches.loc[a.patches["phase"] == "hold", "share_pct"], 50, atol=1.0)
