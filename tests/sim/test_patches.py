"""The simulator against the patch library of ``pito_core.contact``."""

import numpy as np
import pytest

from pito_core import contact
from pito_core.sim import PATCH_HEIGHT, GraspLiveSource, simulate_touches
from pito_core.sim._patches import contacts_on_assembly, point_above


def test_flat_patch_height_matches_library():
    patch = contact.load_patch("flat_46mm")
    assert patch.surface.kind == "plane"
    assert np.allclose(patch.surface.normal, [0, 0, 1])
    assert patch.surface.offset == pytest.approx(PATCH_HEIGHT)


@pytest.mark.parametrize("name", ["cube", "sphere", "ellipsoid", "pito_mixed"])
def test_finger_contacts_lie_on_assembly_surfaces(name):
    asm = contact.load_assembly(name)
    for face, p, n in contacts_on_assembly(name, 5, seed=1):
        surf = asm.patches[face].surface
        if surf.kind in ("sphere", "ellipsoid"):
            q = ((p - surf.center) @ surf.rotation) / surf.semi_axes
            assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-9)
        elif surf.kind == "plane":
            assert p @ surf.normal == pytest.approx(surf.offset)
        assert np.linalg.norm(n) == pytest.approx(1.0)
        assert n[2] > 0  # outward, away from the face


def test_grasp_on_curved_patches_pushes_in():
    src = GraspLiveSource(assembly="pito_mixed", n_fingers=5)
    ct = src.contacts_at(np.linspace(3.6, 8.4, 50))
    fn = np.einsum("nkc,kc->nk", ct["force"], ct["normal"])
    assert np.all(fn < 0)


def test_point_above_refuses_misses():
    with pytest.raises(ValueError, match="surface"):
        point_above(contact.Sphere((0, 0, 0), 0.01), 0.05, 0.0)
    with pytest.raises(ValueError, match="surface"):
        point_above("not a surface", 0, 0)


def test_touches_recovered_by_the_contact_solver():
    # noise-free wrench on the flat patch -> the solver finds the simulated point
    _, tr = simulate_touches(5, "face", 6, k=200)
    F5 = tr.sim.face_wrenches[:, 4]
    sel = -tr.force[:, 2] > 1.0
    est = contact.solve(contact.Plane((0, 0, PATCH_HEIGHT), (0, 0, 1)), F5[sel])
    assert np.all(est.valid)
    assert np.allclose(est.point, tr.point[sel], atol=1e-9)
    assert np.allclose(est.torsion, tr.torsion[sel], atol=1e-9)
