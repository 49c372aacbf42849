"""The simulator's lift task (the analysis's truth): equilibrium at every sample, pushing contacts, face wrenches."""

import numpy as np
import pytest

from pito_core.analysis import net_wrench
from pito_core.contact import solve_object
from pito_core.sim import GRAVITY, LIFT_TRIAL_S, LiftTask


def test_equilibrium_pushing_fingers_and_face_wrenches():
    task = LiftTask(2, mass=0.31, cog=(0.002, 0.001, -0.003), grips=(2.5, 7.0), slides=(0.003, 0.005), seed=4)
    t = np.arange(0, 2 * LIFT_TRIAL_S, 0.003)
    tr = task.truth(t)
    F, M = net_wrench(tr.point, tr.force, tr.torsion, tr.normal, tr.valid, task.cog)
    np.testing.assert_allclose(F, task.mass * (tr.accel - GRAVITY), atol=1e-9)
    np.testing.assert_allclose(M, 0, atol=1e-9)
    fn = -np.einsum("nkj,nkj->nk", tr.force, tr.normal)
    assert (fn[tr.valid] > -1e-12).all()
    assert tr.accel[:, 2].max() > 0.5 and tr.accel[:, 2].min() < -0.5  # it is lifted and put down
    c = solve_object("cube", tr.face_wrenches, 0.2)
    ok = c.valid & tr.valid
    assert ok[:, [0, 2, 5]].any(axis=0).all()
    np.testing.assert_allclose(c.point[ok], tr.point[ok], atol=1e-9)
    np.testing.assert_allclose(c.force[ok], tr.force[ok], atol=1e-9)


@pytest.mark.parametrize("kw, field", [({"n_trials": 0}, "n_trials"), ({"mass": -1}, "mass"),
                                      ({"grips": (1.0,)}, "grips")])
def test_bad_settings_name_the_field(kw, field):
    with pytest.raises(ValueError, match=field):
        LiftTask(**{"n_trials": 2, **kw})
