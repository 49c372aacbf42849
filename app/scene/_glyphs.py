"""The contact glyphs: per face, a contact sphere, a force arrow, a torsion ring, a clamp collar, an ellipsoid.

Built once per scene; :meth:`ContactGlyphs.update` only moves them (``user_matrix``,
positions) and toggles their visibility (STYLE.md item 10). Their poses are
:mod:`app.scene._poses`'s. Core frame, metres.
"""

from __future__ import annotations

import numpy as np
import pyvista as pv

from pito_core.defaults import SHOW_CONTACT_FORCE_N
from pito_core.frames import FACES

from ..palette import CONTACT_COLOR, FACE_COLORS, FLAGGED_CONTACT_COLOR, hex_rgb
from ._poses import arrow_matrix, disc_matrix, ellipsoid_matrix

__all__ = ["ContactGlyphs", "FULL_SCALE_FORCE"]

#: N: arrows are drawn up to this force (a firm grasp, the arrows' full scale) and clamped beyond it
#: (marked by a white collar at the tail); the live view frames its camera to hold them
FULL_SCALE_FORCE = 12.0


class ContactGlyphs:
    """One contact sphere, force arrow, torsion ring and uncertainty ellipsoid per face.

    Created once; :meth:`update` moves them in place and hides the faces whose force is
    under ``threshold`` (N) or whose estimate is not valid. The contact is a white sphere
    centred on the contact point, drawn with the rest of the scene (depth-tested: a contact
    on a face turned away is hidden by the object, as its arrow is); the arrow, in the face's
    colour (the colour of its curve in the plots), ends on the sphere's surface. Arrows
    longer than :data:`FULL_SCALE_FORCE` are clamped to it and get a white collar at the tail.
    Torsion rings float a little above the surface (a ring in the surface's plane z-fights
    with it).

    The uncertainty ellipsoid is the 2σ region of the contact point (its covariance from the
    solver, m²). It is drawn only where it says something: not when its largest semi-axis is
    over ``max_ellipsoid`` (half the cube's edge: a light touch whose point the face cannot
    place), nor when it fits inside the contact sphere (a firm touch: the point is known
    better than the sphere's radius). :attr:`ellipsoid_scale` magnifies the drawn ellipsoid
    (its size on screen is ``ellipsoid_scale`` × 2σ; the "too wide" rule is on the true 2σ).
    :attr:`ellipsoid_state` tells which, per face, and :attr:`ellipsoid_size` the true largest
    2σ semi-axis (m, NaN: none); :meth:`ellipsoid_note` says it in words.

    A contact that one fingertip cannot explain (``single_contact`` False: two fingers on
    one patch, or a load beyond a fingertip's friction; docs/contact.md) gets a red-pink
    sphere (:data:`~app.palette.FLAGGED_CONTACT_COLOR`) instead of the white one;
    :attr:`flagged` (6,) says which.

    :meth:`set_contact_color` is the per-contact state hook: a face's sphere takes the given
    colour (e.g. a flagged contact) until it is reset to ``None``.

    Parameters
    ----------
    plotter : pyvista plotter
    edge : float
        Cube edge, m (sets glyph sizes).
    """

    def __init__(self, plotter, edge: float):

        self.plotter = plotter
        self.force_scale = 0.006  # m per N: 15 N -> 9 cm
        self.torque_scale = 0.25  # m per N·m: 0.1 N·m -> 2.5 cm ring radius
        self.threshold = SHOW_CONTACT_FORCE_N  # N
        self.full_scale = FULL_SCALE_FORCE  # N
        self.show_torsion = True
        self.show_uncertainty = False
        self.radius = 0.07 * edge  # m, contact sphere
        self.max_ellipsoid = 0.5 * edge  # m: largest ellipsoid semi-axis drawn (see the class docstring)
        self.ellipsoid_scale = 1.0  # drawn size / true 2σ size
        self.lift = 0.04 * edge  # m, torsion rings above the surface
        unit_arrow = pv.Arrow(start=(0, 0, 0), direction=(1, 0, 0), tip_length=0.25, tip_radius=2.2, shaft_radius=1.0, scale=1.0)
        # pv.Arrow scales radii by `scale` (=1): radii are in "width" units, length is 1
        unit_sphere = pv.Sphere(radius=1.0, theta_resolution=20, phi_resolution=12)
        ring = pv.Disc(inner=0.82, outer=1.0, r_res=1, c_res=48)
        collar = pv.Disc(inner=0.0, outer=1.0, r_res=1, c_res=24)
        self._width = 0.0022 * edge / 0.05
        sphere_src = pv.Sphere(radius=self.radius, theta_resolution=16, phi_resolution=12)
        self.spheres, self.arrows, self.rings, self.ellipsoids, self.collars = {}, {}, {}, {}, {}
        for i in FACES:
            c = FACE_COLORS[i]
            sph = plotter.add_mesh(sphere_src.copy(), color=CONTACT_COLOR, name=f"contact_sphere_{i}",
                                   reset_camera=False, smooth_shading=True)
            sph.prop.ambient = 0.35
            self.spheres[i] = sph
            self.arrows[i] = plotter.add_mesh(unit_arrow.copy(), color=c, name=f"force_arrow_{i}", reset_camera=False)
            # opaque: a translucent actor costs every frame an extra pass in software GL (~1.6x)
            self.rings[i] = plotter.add_mesh(ring.copy(), color=c, name=f"torsion_ring_{i}", reset_camera=False)
            self.collars[i] = plotter.add_mesh(collar.copy(), color=CONTACT_COLOR, name=f"clamp_collar_{i}", reset_camera=False)
            self.collars[i].GetProperty().SetLighting(False)  # plain white from any side
            self.ellipsoids[i] = plotter.add_mesh(unit_sphere.copy(), color=c, opacity=0.25, name=f"uncertainty_{i}", reset_camera=False)
        self.shown = np.zeros(6, dtype=bool)
        self.clamped = np.zeros(6, dtype=bool)
        self.flagged = np.zeros(6, dtype=bool)
        #: per face (1..6): "drawn", "inside sphere", "too wide", or "" (no covariance / not shown)
        self.ellipsoid_state = {i: "" for i in FACES}
        self.ellipsoid_size = {i: float("nan") for i in FACES}
        self._contact_colors: dict[int, str] = {}  # face -> sphere colour (the state hook)
        self._sphere_color: dict[int, str] = {i: CONTACT_COLOR for i in FACES}
        self.updates = 0
        self._ring_sign: dict[int, int] = {}
        self._ring_colors = {i: (hex_rgb(FACE_COLORS[i]), tuple(0.45 * v for v in hex_rgb(FACE_COLORS[i]))) for i in FACES}
        self.actors = [a for d in (self.spheres, self.arrows, self.rings, self.ellipsoids, self.collars) for a in d.values()]
        self.hide()

    @property
    def max_length(self) -> float:
        """Longest arrow drawn, m (the full-scale force)."""
        return self.full_scale * self.force_scale

    def reach(self) -> float:
        """How far beyond a contact point a glyph can reach, m (arrow at full scale, sphere)."""
        return self.max_length + 2 * self.radius

    def set_contact_color(self, face: int, color: str | None) -> None:
        """The sphere of ``face``'s contact in ``color`` from the next :meth:`update` on (``None``: white again)."""
        if color is None:
            self._contact_colors.pop(int(face), None)
        else:
            self._contact_colors[int(face)] = color

    def ellipsoid_axes(self, covariance) -> np.ndarray:
        """The 2σ semi-axes (3,) of the contact point's ``covariance`` (3, 3), m, largest last."""
        w = np.linalg.eigvalsh(0.5 * (np.asarray(covariance, float) + np.asarray(covariance, float).T))
        return 2.0 * np.sqrt(np.clip(w, 0.0, None))

    def _ellipsoid_rule(self, covariance) -> str:
        if covariance is None or not np.isfinite(covariance).all():
            return "no covariance"
        top = float(self.ellipsoid_axes(covariance)[-1])
        return ("too wide" if top > self.max_ellipsoid else
                "inside sphere" if top * self.ellipsoid_scale < self.radius else "drawn")

    def ellipsoid_note(self) -> str:
        """Why the ellipsoids of the last update are drawn or not, in one line ("" when not asked for)."""
        if not self.show_uncertainty:
            return ""
        states = [self.ellipsoid_state[i] for i in FACES if self.shown[i - 1]]
        if not states:
            return "ellipsoids: no contact shown"
        if all(s == "no covariance" for s in states):
            return ("ellipsoids: none — the contacts carry no covariance (this calibration has no uncertainty "
                    "record)")
        sizes = [self.ellipsoid_size[i] * 1000 for i in FACES if self.shown[i - 1] and np.isfinite(self.ellipsoid_size[i])]
        parts = [f"{states.count(k)} {w}" for k, w in (
            ("drawn", f"drawn ×{self.ellipsoid_scale:g}"),
            ("inside sphere", f"inside the {self.radius * 1000:.1f} mm spheres at ×{self.ellipsoid_scale:g}"),
            ("too wide", f"wider than {self.max_ellipsoid * 1000:.0f} mm (the face cannot place the point)"))
            if states.count(k)]
        return f"2σ of the contact points {min(sizes):.2f}–{max(sizes):.2f} mm: " + ", ".join(parts)

    def hide(self) -> None:
        for a in self.actors:
            a.SetVisibility(False)
        self.shown = np.zeros(6, dtype=bool)
        self.clamped = np.zeros(6, dtype=bool)

    def shown_count(self) -> int:
        """Contacts on screen after the last update."""
        return int(self.shown.sum())

    def visible(self, contacts) -> np.ndarray:
        """Which faces' glyphs :meth:`update` shows for ``contacts`` (6,): valid, finite, at least ``threshold``."""
        points = np.asarray(contacts.point, dtype=float)
        fnorm = np.linalg.norm(np.asarray(contacts.force, dtype=float), axis=1)
        return np.asarray(contacts.valid, dtype=bool) & np.isfinite(fnorm) & (fnorm >= self.threshold) & np.isfinite(points).all(axis=1)

    def update(self, contacts) -> np.ndarray:
        """Move the glyphs to the latest contacts and return the shown mask (6,).

        Parameters
        ----------
        contacts : pito_core.contact.ContactEstimate
            The one contact record from the solver (core frame), fields of shape ``(6, …)``,
            face i at row i-1: ``point`` (m), ``normal`` (outward), ``force`` on the object
            (N), ``torsion`` about the normal (N·m), ``valid``, ``point_cov`` (m², or None).
        """
        points = np.asarray(contacts.point, dtype=float)
        normals, torsions = contacts.normal, contacts.torsion
        covariances = contacts.point_cov
        forces = np.asarray(contacts.force, dtype=float)
        shown = self.visible(contacts)
        clamped = shown & (np.linalg.norm(forces, axis=1) > self.full_scale)
        single = getattr(contacts, "single_contact", None)  # None: a record without the single-contact test
        flagged = shown & ~np.asarray(single, dtype=bool) if single is not None else np.zeros(6, dtype=bool)
        for k, i in enumerate(FACES):
            on = bool(shown[k])
            self.spheres[i].SetVisibility(on)
            self.arrows[i].SetVisibility(on)
            self.collars[i].SetVisibility(bool(clamped[k]))
            tor = float(torsions[k]) if on else np.nan
            ring_on = bool(on and self.show_torsion and np.isfinite(tor) and abs(tor) * self.torque_scale > 1e-4)
            self.rings[i].SetVisibility(ring_on)
            state = ""
            if on and self.show_uncertainty:
                state = self._ellipsoid_rule(None if covariances is None else covariances[k])
            self.ellipsoid_state[i] = state
            self.ellipsoid_size[i] = (float(self.ellipsoid_axes(covariances[k])[-1])
                                      if state not in ("", "no covariance") else float("nan"))
            cov_on = state == "drawn"
            self.ellipsoids[i].SetVisibility(cov_on)
            if on:
                self._move(i, points[k], forces[k], bool(clamped[k]), bool(flagged[k]))
            if ring_on:
                self._move_ring(i, points[k], normals[k], tor)
            if cov_on:
                self.ellipsoids[i].user_matrix = ellipsoid_matrix(points[k], covariances[k], 2.0 * self.ellipsoid_scale)
        self.shown = shown
        self.clamped = clamped
        self.flagged = flagged
        self.updates += 1
        return shown

    def _move(self, i: int, point, force, clamped: bool, flagged: bool = False) -> None:
        """Face ``i``'s sphere to ``point`` (m), its arrow to ``force`` (N) there, its collar if ``clamped``;
        the sphere red-pink if ``flagged`` (unless :meth:`set_contact_color` says otherwise)."""
        self.spheres[i].SetPosition(*point)
        color = self._contact_colors.get(i, FLAGGED_CONTACT_COLOR if flagged else CONTACT_COLOR)
        if self._sphere_color[i] != color:  # (a colour set costs a pyvista round trip)
            self._sphere_color[i] = color
            self.spheres[i].prop.color = color
        M = arrow_matrix(point, force, self.force_scale, self._width, self.max_length, self.radius)
        self.arrows[i].user_matrix = M
        if clamped:
            # a white collar around the tail of a clamped arrow: "more than full scale"
            tail = M[:3, 3]
            self.collars[i].user_matrix = disc_matrix(tail, force, 4.0 * self._width)

    def _move_ring(self, i: int, point, normal, torsion: float) -> None:
        """Face ``i``'s torsion ring: ``lift`` above ``point`` (m), facing ``normal``, radius by ``torsion`` (N·m)."""
        n = np.asarray(normal, dtype=float)
        n_norm = np.linalg.norm(n)
        centre = point + (self.lift * n / n_norm if n_norm > 0 else 0.0)
        self.rings[i].user_matrix = disc_matrix(centre, normal, abs(torsion) * self.torque_scale)
        # the sign of the torsion: full colour counter-clockwise (τ > 0), dimmed clockwise
        sign = 0 if torsion > 0 else 1
        if self._ring_sign.get(i) != sign:  # (a colour set costs a pyvista round trip)
            self._ring_sign[i] = sign
            self.rings[i].prop.color = self._ring_colors[i][sign]
