"""The patch library: patch and assembly files in ``assets/patches/``.

Patch file (JSON, ``"format": "pito-patch"``, ``"version": 1``)::

    {"format": "pito-patch", "version": 1, "name": "flat_46mm", "description": "...",
     "surface": {"type": "plane", "point": [0, 0, 0.003], "normal": [0, 0, 1]},
     "boundary": {"shape": "rectangle", "size": [0.046, 0.046], "projection": "parallel"},
     "display": {"base_z": 0.0, "rings": 12, "segments": 96},
     "friction": {"mu": 1.0, "torsion_radius": 0.005}}

Surface types: ``plane`` (point, normal), ``sphere`` (center, radius), ``ellipsoid``
(center, semi_axes, optional rotation 3×3 whose columns are the principal axes) and
``mesh`` (file: STL/OBJ/PLY next to the JSON). All values in the face frame, in m.
``friction`` (optional) gives the fingertip–patch friction coefficient ``mu`` and the
fingertip's effective torsional radius ``torsion_radius`` (m) of the single-contact test
(defaults ``DEFAULT_FRICTION``, ``DEFAULT_TORSION_RADIUS``).
``display`` either parametrises the generated solid (analytic surfaces) or names a mesh
``file``; a mesh surface is its own display mesh.

Assembly file (``"format": "pito-assembly"``)::

    {"format": "pito-assembly", "version": 1, "name": "cube", "core_edge": 0.05,
     "faces": {"1": "flat_46mm", ..., "6": "flat_46mm"},
     "mass": null, "center_of_gravity": null}
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..frames import FACES, CubeCore
from ._boundary import PatchBoundary
from ._display import patch_solid
from ._plausibility import DEFAULT_FRICTION, DEFAULT_TORSION_RADIUS
from ._solve import solve
from ._surfaces import Ellipsoid, MeshSurface, Plane, Sphere

# trimesh is imported where a mesh is loaded or built (below): it takes ~1 s to import, and
# the analytic patches (the bare cube, most live sessions) never need it.

__all__ = [
    "Patch",
    "Assembly",
    "patches_dir",
    "load_patch",
    "load_assembly",
    "list_patches",
    "list_assemblies",
    "surface_from_dict",
    "surface_to_dict",
]

PATCH_FORMAT = "pito-patch"
ASSEMBLY_FORMAT = "pito-assembly"
FORMAT_VERSION = 1


def patches_dir() -> Path:
    """The directory of the built-in patch library (``<repo>/assets/patches``).

    Same as ``Path(pito_core.__file__).resolve().parents[1] / "assets" / "patches"``,
    without importing the ``pito_core`` package (``contact`` stays independent of
    ``calibration``).
    """
    return Path(__file__).resolve().parents[2] / "assets" / "patches"


def _read_json(path: Path, fmt: str) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(d, dict) or d.get("format") != fmt:
        raise ValueError(f"{path}: expected a '{fmt}' file (key 'format')")
    if d.get("version") != FORMAT_VERSION:
        raise ValueError(f"{path}: unsupported version {d.get('version')!r}, expected {FORMAT_VERSION}")
    return d


def _load_mesh(path: Path):
    import trimesh  # deferred: ~1 s to import (note at the imports)

    if path.suffix.lower() not in (".stl", ".obj", ".ply"):
        raise ValueError(f"file: expected an STL, OBJ or PLY mesh, got {path.name}")
    if not path.is_file():
        raise ValueError(f"file: mesh {path} not found")
    mesh = trimesh.load(path, force="mesh")
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"file: {path} holds no triangle mesh")
    return mesh


def surface_from_dict(d: dict, base_dir: Path | None = None):
    """A surface from its JSON description (face frame, m)."""
    if not isinstance(d, dict) or "type" not in d:
        raise ValueError("surface: expected an object with a 'type'")
    t = d["type"]
    try:
        if t == "plane":
            return Plane(d["point"], d["normal"])
        if t == "sphere":
            return Sphere(d["center"], d["radius"])
        if t == "ellipsoid":
            return Ellipsoid(d["center"], d["semi_axes"], d.get("rotation"))
        if t == "mesh":
            return MeshSurface(_load_mesh(Path(base_dir or ".") / d["file"]))
    except KeyError as exc:
        raise ValueError(f"surface: type '{t}' needs key {exc.args[0]!r}") from None
    raise ValueError(f"surface: unknown type {t!r} (plane, sphere, ellipsoid, mesh)")


def surface_to_dict(surface) -> dict:
    """JSON description of an analytic surface (meshes are stored as files)."""
    if isinstance(surface, Plane):
        return {"type": "plane", "point": surface.point.tolist(), "normal": surface.normal.tolist()}
    if isinstance(surface, Sphere):
        return {"type": "sphere", "center": surface.center.tolist(), "radius": surface.radius}
    if isinstance(surface, Ellipsoid):
        return {
            "type": "ellipsoid",
            "center": surface.center.tolist(),
            "semi_axes": surface.semi_axes.tolist(),
            "rotation": surface.rotation.tolist(),
        }
    raise ValueError(f"surface: cannot describe {type(surface).__name__} as JSON")


class Patch:
    """A surface patch screwed on a face: surface, boundary and display mesh (face frame).

    Parameters
    ----------
    surface : Plane, Sphere, Ellipsoid or MeshSurface
        The exact surface used by the solver.
    boundary : PatchBoundary, optional
        The part of the surface that belongs to the patch.
    name, description : str
    display : dict or trimesh.Trimesh, optional
        Generated-solid parameters (``base_z``, ``rings``, ``segments``) or a mesh.
    mu : float
        Fingertip–patch friction coefficient of the single-contact test (dimensionless).
    torsion_radius : float
        Fingertip's effective torsional radius, m (largest torsion ``μ · torsion_radius · f_n``).
    """

    def __init__(self, surface, boundary=None, *, name="patch", description="", display=None,
                 mu=DEFAULT_FRICTION, torsion_radius=DEFAULT_TORSION_RADIUS):
        for key, v in (("mu", mu), ("torsion_radius", torsion_radius)):
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not np.isfinite(v) or v <= 0:
                raise ValueError(f"friction: {key}: expected a positive number, got {v!r}")
        self.mu = float(mu)
        self.torsion_radius = float(torsion_radius)
        self.surface = surface
        self.boundary = boundary
        self.name = name
        self.description = description
        self._display = display
        self._mesh = None

    def display_mesh(self):
        """Closed ``trimesh.Trimesh`` of the patch in its face frame (m), cached."""
        if self._mesh is None:
            import trimesh  # deferred: ~1 s to import (note at the imports)

            if isinstance(self._display, trimesh.Trimesh):
                self._mesh = self._display
            elif isinstance(self.surface, MeshSurface):
                self._mesh = self.surface.mesh
            else:
                opts = dict(self._display or {})
                if self.boundary is None or self.boundary.shape is None:
                    raise ValueError(f"{self.name}: an analytic patch needs a boundary shape to be displayed")
                self._mesh = patch_solid(self.surface, self.boundary, **opts)
        return self._mesh

    def solve(self, wrench, **kwargs):
        """``solve(self, wrench, **kwargs)``: contacts on this patch (see ``solve``)."""
        return solve(self, wrench, **kwargs)

    @classmethod
    def from_dict(cls, d: dict, base_dir: Path | None = None) -> Patch:
        surface = surface_from_dict(d.get("surface"), base_dir)
        boundary = PatchBoundary.from_dict(d["boundary"]) if d.get("boundary") else None
        display = d.get("display")
        if isinstance(display, dict) and "file" in display:
            display = _load_mesh(Path(base_dir or ".") / display["file"])
        elif display is not None and not isinstance(display, dict):
            raise ValueError("display: expected an object")
        elif isinstance(display, dict):
            extra = set(display) - {"base_z", "rings", "segments"}
            if extra:
                raise ValueError(f"display: unknown keys {sorted(extra)}")
        fr = d.get("friction") or {}
        if not isinstance(fr, dict) or set(fr) - {"mu", "torsion_radius"}:
            raise ValueError("friction: expected an object with keys 'mu', 'torsion_radius'")
        return cls(surface, boundary, name=d.get("name", "patch"), description=d.get("description", ""),
                   display=display, mu=fr.get("mu", DEFAULT_FRICTION),
                   torsion_radius=fr.get("torsion_radius", DEFAULT_TORSION_RADIUS))

    def __repr__(self):
        return f"Patch({self.name!r}, {self.surface!r})"


def load_patch(name_or_path) -> Patch:
    """A patch by library name (``"flat_46mm"``) or from a ``.json`` path."""
    p = Path(name_or_path)
    if p.suffix != ".json":
        p = patches_dir() / f"{name_or_path}.json"
    d = _read_json(p, PATCH_FORMAT)
    try:
        return Patch.from_dict(d, p.parent)
    except ValueError as exc:
        raise ValueError(f"{p.name}: {exc}") from None


def _list(fmt: str) -> list[str]:
    out = []
    for p in sorted(patches_dir().glob("*.json")):
        try:
            d = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError):
            continue
        if isinstance(d, dict) and d.get("format") == fmt:
            out.append(p.stem)
    return out


def list_patches() -> list[str]:
    """Names of the patches in the library."""
    return _list(PATCH_FORMAT)


def list_assemblies() -> list[str]:
    """Names of the object assemblies in the library (``cube``, ``sphere``, ...)."""
    return _list(ASSEMBLY_FORMAT)


class Assembly:
    """An object: the core and one patch per face.

    Attributes
    ----------
    name : str
    core : CubeCore
    patches : dict[int, Patch]
        Patch on each face 1..6 (face frames).
    mass : float or None
        Mass of the object, kg (optional, for equilibrium checks).
    center_of_gravity : ndarray, shape (3,), or None
        Centre of gravity in the core frame, m.
    """

    def __init__(self, name, core, patches, *, description="", mass=None, center_of_gravity=None):
        missing = [i for i in FACES if i not in patches]
        if missing:
            raise ValueError(f"faces: expected a patch for every face 1..6, missing {missing}")
        self.name = name
        self.core = core
        self.patches = {i: patches[i] for i in FACES}
        self.description = description
        self.mass = None if mass is None else float(mass)
        self.center_of_gravity = None if center_of_gravity is None else np.asarray(center_of_gravity, float)

    def face_mesh(self, face: int):
        """Display mesh of the patch on ``face`` in the core frame (``trimesh.Trimesh``, m)."""
        mesh = self.patches[face].display_mesh().copy()
        mesh.apply_transform(self.core.face_pose(face))
        return mesh

    def core_mesh(self):
        """The core cube in the core frame (``trimesh.Trimesh``, m)."""
        import trimesh  # deferred: ~1 s to import (note at the imports)

        return trimesh.creation.box(extents=(self.core.edge,) * 3)

    def bodies(self) -> list:
        """Core and the six patch meshes, core frame: the object's closed parts."""
        return [self.core_mesh()] + [self.face_mesh(i) for i in FACES]

    def mesh(self):
        """All parts concatenated into one ``trimesh.Trimesh`` (core frame, m)."""
        import trimesh  # deferred: ~1 s to import (note at the imports)

        return trimesh.util.concatenate(self.bodies())

    def __repr__(self):
        return f"Assembly({self.name!r}, edge={self.core.edge}, " + \
            ", ".join(f"{i}: {p.name}" for i, p in self.patches.items()) + ")"


def load_assembly(name_or_path) -> Assembly:
    """An assembly by library name (``"cube"``, ``"sphere"``, ``"ellipsoid"``,
    ``"pito_mixed"``) or from a ``.json`` path; its patches are looked up next to it."""
    p = Path(name_or_path)
    if p.suffix != ".json":
        p = patches_dir() / f"{name_or_path}.json"
    d = _read_json(p, ASSEMBLY_FORMAT)
    faces = d.get("faces")
    if not isinstance(faces, dict):
        raise ValueError(f"{p.name}: faces: expected an object mapping '1'..'6' to patch names")
    cache: dict[str, Patch] = {}
    patches = {}
    for key, pname in faces.items():
        try:
            i = int(key)
        except ValueError:
            raise ValueError(f"{p.name}: faces: expected keys '1'..'6', got {key!r}") from None
        if i not in FACES:
            raise ValueError(f"{p.name}: faces: expected keys '1'..'6', got {key!r}")
        if pname not in cache:
            cache[pname] = load_patch(p.parent / f"{pname}.json")
        patches[i] = cache[pname]
    return Assembly(
        d.get("name", p.stem),
        CubeCore(d.get("core_edge", 0.05)),
        patches,
        description=d.get("description", ""),
        mass=d.get("mass"),
        center_of_gravity=d.get("center_of_gravity"),
    )
