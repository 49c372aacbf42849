"""The patched object as the app shows it: the library's assemblies, display meshes, weight."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pyvista as pv

import pito_core
from pito_core.contact import list_assemblies as _list_assemblies
from pito_core.contact import load_assembly, patches_dir
from pito_core.frames import FACES

from .demo import cache_dir
from .scene import PATCH_DISPLAY_CELLS

__all__ = ["list_assemblies", "load_assembly", "display_meshes", "weight"]


def list_assemblies() -> list[str]:
    """Object assemblies of the patch library (``assets/patches/``), ``pito_mixed`` first."""
    return sorted(_list_assemblies(), key=lambda n: (n != "pito_mixed", n))


def display_meshes(assembly, name: str | None = None) -> dict | None:
    """Face → pyvista mesh (core frame, m) of each patch, or None for the bare cube.

    A patch of more than ``PATCH_DISPLAY_CELLS`` triangles is decimated to about that many
    (software GL pays per vertex every frame; the smooth-shaded patch looks the same); the
    decimated mesh is cached in the app's cache (``app.demo.cache_dir``) under the hash of the
    mesh it comes from, so a later start skips the decimation.

    ``name``: the library name ``assembly`` was loaded by (:func:`list_assemblies`). The six meshes
    are then cached together under the hash of its description (:func:`_library_key`: the
    library's files and the code that builds the meshes), so a later start reads them back
    without building any patch mesh (no trimesh: a third of a second at start-up).
    """
    if assembly is None:
        return None
    key = _library_key(name) if name is not None else None
    paths = {i: cache_dir() / f"display-{key}-{i}.vtp" for i in FACES} if key else {}
    cached = {i: _read_vtp(p) for i, p in paths.items()}
    if paths and all(m is not None for m in cached.values()):
        return cached
    meshes = {i: _display_mesh(assembly.face_mesh(i)) for i in FACES}
    for i, path in paths.items():
        _write_vtp(meshes[i], path)
    return meshes


def _library_key(name: str) -> str | None:
    """Hash of what makes library assembly ``name``'s display meshes, or None if ``name`` is not in the library.

    The description is the library's files (``assets/patches``: the assembly, its patches and
    their meshes), the source of ``pito_core`` ``contact`` and ``frames`` (which build and place the
    patch solids), :data:`PATCH_DISPLAY_CELLS` and pyvista's version."""
    lib = patches_dir()
    if not (lib / f"{name}.json").is_file():
        return None
    h = hashlib.sha256(f"{name}/{PATCH_DISPLAY_CELLS}/{pv.__version__}".encode())
    root = Path(pito_core.__file__).parent
    files = sorted(p for p in lib.iterdir() if p.is_file())
    files += [f for pkg in ("contact", "frames") for f in sorted((root / pkg).rglob("*.py"))]
    for f in files:
        h.update(f.name.encode())
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()[:20]


def _read_vtp(path: Path):
    """A mesh this cache wrote (VTK XML poly data), or None when missing or damaged (a damaged file is removed)."""
    if not path.is_file():
        return None
    with open(path, "rb") as f:
        head = f.read(64)
    cached = pv.read(path) if head.lstrip().startswith(b"<") else None  # VTK XML; anything else is damaged
    if cached is not None and cached.n_cells > 0:
        return cached
    path.unlink(missing_ok=True)  # made again by the caller
    return None


def _write_vtp(mesh, path: Path) -> None:
    """Write ``mesh`` to ``path`` whole or not at all (a temporary name, then a rename); not in a read-only cache."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.stem + ".partial.vtp")
        mesh.save(tmp)
        tmp.replace(path)
    except OSError:  # a read-only home: built at every start, as before
        pass


def _display_mesh(tri):
    mesh = pv.wrap(tri)
    if mesh.n_cells <= PATCH_DISPLAY_CELLS:
        return mesh
    h = hashlib.sha256(np.ascontiguousarray(tri.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(tri.faces, dtype=np.int64).tobytes())
    h.update(f"{PATCH_DISPLAY_CELLS}/{pv.__version__}".encode())
    path = cache_dir() / f"patch-{h.hexdigest()[:20]}.vtp"
    cached = _read_vtp(path)
    if cached is not None:
        return cached
    small = mesh.triangulate().decimate(1.0 - PATCH_DISPLAY_CELLS / mesh.n_cells)
    _write_vtp(small, path)
    return small


def weight(assembly) -> float:
    """m·g of the object, N (0.3 kg when the assembly does not say)."""
    mass = getattr(assembly, "mass", None)
    return float(mass if mass else 0.3) * 9.81
