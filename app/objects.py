"""The patched object as the app shows it: the library's assemblies, display meshes, weight."""

from __future__ import annotations

import hashlib

import numpy as np
import pyvista as pv

from pito_core.contact import list_assemblies as _list_assemblies
from pito_core.contact import load_assembly
from pito_core.frames import FACES

from .demo import cache_dir
from .scene import PATCH_DISPLAY_CELLS

__all__ = ["list_assemblies", "load_assembly", "display_meshes", "weight"]


def list_assemblies() -> list[str]:
    """Object assemblies of the patch library (``assets/patches/``), ``pito_mixed`` first."""
    return sorted(_list_assemblies(), key=lambda n: (n != "pito_mixed", n))


def display_meshes(assembly) -> dict | None:
    """Face → pyvista mesh (core frame, m) of each patch, or None for the bare cube.

    A patch of more than ``PATCH_DISPLAY_CELLS`` triangles is decimated to about that many
    (software GL pays per vertex every frame; the smooth-shaded patch looks the same); the
    decimated mesh is cached in the app's cache (``app.demo.cache_dir``) under the hash of the
    mesh it comes from, so a later start skips the decimation.
    """
    if assembly is None:
        return None
    return {i: _display_mesh(assembly.face_mesh(i)) for i in FACES}


def _display_mesh(tri):
    mesh = pv.wrap(tri)
    if mesh.n_cells <= PATCH_DISPLAY_CELLS:
        return mesh
    h = hashlib.sha256(np.ascontiguousarray(tri.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(tri.faces, dtype=np.int64).tobytes())
    h.update(f"{PATCH_DISPLAY_CELLS}/{pv.__version__}".encode())
    path = cache_dir() / f"patch-{h.hexdigest()[:20]}.vtp"
    if path.is_file():
        with open(path, "rb") as f:
            head = f.read(64)
        cached = pv.read(path) if head.lstrip().startswith(b"<") else None  # VTK XML; anything else is damaged
        if cached is not None and cached.n_cells > 0:
            return cached
        path.unlink(missing_ok=True)  # a damaged cache file: made again below
    small = mesh.triangulate().decimate(1.0 - PATCH_DISPLAY_CELLS / mesh.n_cells)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.stem + ".partial.vtp")
        small.save(tmp)
        tmp.replace(path)
    except OSError:  # a read-only home: decimated at every start, as before
        pass
    return small


def weight(assembly) -> float:
    """m·g of the object, N (0.3 kg when the assembly does not say)."""
    mass = getattr(assembly, "mass", None)
    return float(mass if mass else 0.3) * 9.81
