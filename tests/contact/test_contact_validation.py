"""One ``pytest.raises`` per validator at the edge of ``pito_core.contact``."""

import subprocess
import sys

import numpy as np
import pytest
import trimesh

from pito_core.contact import (
    Ellipsoid,
    MeshSurface,
    PatchBoundary,
    Plane,
    Sphere,
    contact_crb,
    load_patch,
    solve,
    solve_object,
)

S = Sphere([0, 0, 0], 0.02)


@pytest.mark.parametrize("call,match", [
    (lambda: Plane([0, 0], [0, 0, 1]), "point: expected shape \\(3,\\)"),
    (lambda: Plane([0, 0, 0], [0, 0, 0]), "normal: expected a non-zero vector"),
    (lambda: Plane([0, 0, np.nan], [0, 0, 1]), "point: expected finite values"),
    (lambda: Sphere([0, 0, 0], -1.0), "radius: expected a positive length"),
    (lambda: Sphere([0, 0, 0], "big"), "radius: expected a positive length"),
    (lambda: Ellipsoid([0, 0, 0], [0.01, 0.0, 0.01]), "semi_axes: expected three positive lengths"),
    (lambda: Ellipsoid([0, 0, 0], [0.01] * 3, np.diag([1.0, 1.0, -1.0])), "rotation: expected a proper rotation"),
    (lambda: Ellipsoid([0, 0, 0], [0.01] * 3, np.eye(2)), "rotation: expected a finite \\(3, 3\\)"),
    (lambda: MeshSurface("mesh.stl"), "mesh: expected a trimesh.Trimesh"),
    (lambda: MeshSurface(trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]], process=False)),
     "mesh: expected at least one non-degenerate facet"),
    (lambda: MeshSurface(trimesh.Trimesh()), "mesh: expected at least one facet"),
    (lambda: solve("sphere", [0] * 6), "surface: expected a Plane, Sphere"),
    (lambda: solve(S, [0] * 5), "wrench: expected shape \\(..., 6\\)"),
    (lambda: solve(S, [0] * 6, force_threshold=-1), "force_threshold: expected a force >= 0"),
    (lambda: solve(S, [0] * 6, wrench_cov=np.eye(5)), "wrench_cov: expected shape \\(6, 6\\)"),
    (lambda: solve(S, [0] * 6, wrench_cov=np.triu(np.ones((6, 6)))), "wrench_cov: expected a symmetric"),
    (lambda: solve(S, [0] * 6, wrench_cov=-np.eye(6)), "wrench_cov: expected a positive definite"),
    (lambda: solve(S, [0] * 6, wrench_cov=np.full((6, 6), np.nan)), "wrench_cov: expected finite"),
    (lambda: contact_crb(S, np.zeros((2, 3)), np.zeros((3, 3)), np.eye(6)), "force: expected shape \\(2, 3\\)"),
    (lambda: contact_crb(S, np.zeros((2, 3)), np.zeros((2, 3)), np.eye(6), torsion=[0]), "torsion: expected shape"),
    (lambda: PatchBoundary("circle"), "shape: expected one of"),
    (lambda: PatchBoundary("rectangle", size=[0.01]), "size: expected two positive lengths"),
    (lambda: PatchBoundary("ellipse", radii=[0.01, -1]), "radii: expected two positive lengths"),
    (lambda: PatchBoundary("polygon", vertices=[[0, 0], [1, 0]]), "vertices: expected shape"),
    (lambda: PatchBoundary("polygon", vertices=[[0, 0], [0, 1], [1, 0]]), "vertices: expected a counter-clockwise"),
    (lambda: PatchBoundary("rectangle", size=[1, 1], projection="fisheye"), "projection: expected"),
    (lambda: PatchBoundary("rectangle", size=[1, 1], projection="central", apex=[0, 0, 1]), "apex: expected a point"),
    (lambda: PatchBoundary(None, z_min=np.inf), "z_min: expected a finite height"),
    (lambda: PatchBoundary(None, center=[0, 0, 0]), "center: expected shape \\(2,\\)"),
    (lambda: PatchBoundary.from_dict([1]), "boundary: expected an object"),
    (lambda: solve_object("cube", np.zeros((4, 5, 6))), "face_wrenches: expected shape \\(..., 6, 6\\)"),
    (lambda: solve_object("cube", np.zeros((6, 6)), wrench_cov=np.eye(3)), "wrench_cov: expected shape"),
    (lambda: solve_object(42, np.zeros((6, 6))), "assembly: expected an Assembly"),
    (lambda: PatchBoundary(None).outline(), "outline: a boundary without shape"),
    (lambda: load_patch("faceted_dome").surface._index.__class__(np.zeros((1, 3, 3)), 0), "group_size"),
])
def test_validators_name_the_field(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_contact_imports_no_gui_and_no_calibration():
    """The import-linter contracts, checked on our own sources (AST) and at run time."""
    import ast
    from pathlib import Path

    import pito_core.contact as contact

    forbidden = ("PySide6", "pyvista", "pyvistaqt", "pyqtgraph", "app", "pito_core.calibration")
    for path in Path(contact.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [("." * node.level) + (node.module or "")]
            else:
                continue
            for name in names:
                assert not name.startswith(forbidden), f"{path.name} imports {name}"
                assert not name.startswith("..calibration"), f"{path.name} imports {name}"
    code = (
        "import sys; import pito_core.contact, pito_core.contact._display;"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('PySide6', 'pyvista', 'pyvistaqt', 'app')];"
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
