"""``Calibration``: a fitted matrix that turns counts into the wrench on each face."""

from __future__ import annotations

import numpy as np

from ..frames import FACES, N_GAUGES, CubeCore, check_pose, invert_pose, wrench_adjoint
from ..io import FileFormatError, read_calibration_fields, write_calibration
from ._coverage import Coverage
from ._cv import ModelChoice
from ._poly import PolyCorrection
from ._error import CalibrationCovariance, CovarianceGroup
from ._methods import get_method

__all__ = ["Calibration", "load_calibration"]


class Calibration:
    """A fitted calibration: counts → wrench on each face, in face frames.

    Parameters
    ----------
    method : str
        The method that fitted it.
    matrix : array-like, shape (6·F, 36)
        The matrix as fitted: rows ``6k .. 6k+5`` give ``[fx, fy, fz, tx, ty, tz]``
        (N, N·m) of face ``output_faces[k]`` from offset-free counts, in the frame
        ``output_frame``.
    output_faces : sequence of int
        Faces (1..6) the matrix outputs, in row order.
    output_frame : {"face", "reference"}
        ``face``: each face's rows are in its own frame. ``reference``: in the
        reference frame S_A given by ``T_core_ati`` (the ``loaded_frame`` method).
    offset : array-like, shape (36,)
        Unloaded counts subtracted before the matrix (the tare), counts.
    core : CubeCore
    T_core_ati : array-like, shape (4, 4)
        Pose of the reference frame S_A in the core frame at calibration.
    meta : dict
        Method, mount, date, samples, validation figures (JSON-serialisable).
    covariance : CalibrationCovariance, optional
        The fit's uncertainty (residual covariance, design, gauge noise); None for
        calibrations without it (files of format version 1).
    correction : PolyCorrection, optional
        The nonlinear part (model ``poly``): rows as ``matrix``'s, of the offset-free
        counts; None for the papers' linear model.
    model : ModelChoice, optional
        Which model the fit chose and the cross-validated figures that chose it
        (default: ``linear``, as files written before the choice existed).
    linear_fit : (matrix, offset), optional
        With the ``poly`` model: the papers' linear fit of the same data (``matrix`` as
        above, ``offset (36,)`` counts), for :meth:`linear_alternative`.
    """

    def __init__(self, method, matrix, output_faces, output_frame, offset, core, T_core_ati, meta=None,
                 covariance=None, correction=None, model=None, linear_fit=None):
        self.method = str(method)
        output_faces = tuple(int(f) for f in output_faces)
        if not output_faces or any(f not in FACES for f in output_faces) or len(set(output_faces)) != len(output_faces):
            raise ValueError(f"output_faces: expected distinct faces 1..6, got {output_faces}")
        matrix = np.asarray(matrix, dtype=float)
        if matrix.shape != (6 * len(output_faces), N_GAUGES):
            raise ValueError(f"matrix: expected shape ({6 * len(output_faces)}, {N_GAUGES}), got {matrix.shape}")
        if not np.all(np.isfinite(matrix)):
            raise ValueError("matrix: expected finite values")
        if output_frame not in ("face", "reference"):
            raise ValueError(f"output_frame: expected 'face' or 'reference', got {output_frame!r}")
        offset = np.asarray(offset, dtype=float)
        if offset.shape != (N_GAUGES,):
            raise ValueError(f"offset: expected shape ({N_GAUGES},), got {offset.shape}")
        if not isinstance(core, CubeCore):
            raise ValueError(f"core: expected a CubeCore, got {type(core).__name__}")
        self.matrix = matrix
        self.output_faces = output_faces
        self.output_frame = output_frame
        self.offset = offset
        self.core = core
        self.T_core_ati = check_pose(T_core_ati, "T_core_ati")
        self.meta = {} if meta is None else dict(meta)
        if covariance is not None and not isinstance(covariance, CalibrationCovariance):
            raise ValueError(f"covariance: expected a CalibrationCovariance or None, got {type(covariance).__name__}")
        self.covariance = covariance
        if correction is not None:
            if not isinstance(correction, PolyCorrection):
                raise ValueError(f"correction: expected a PolyCorrection or None, got {type(correction).__name__}")
            if correction.coef.shape[0] != matrix.shape[0] or correction.scale.shape != (N_GAUGES,):
                raise ValueError(f"correction: expected {matrix.shape[0]} rows over {N_GAUGES} gauges, got "
                                 f"{correction.coef.shape[0]} rows over {correction.scale.size}")
        self.correction = correction
        if model is None:
            model = ModelChoice(name="linear" if correction is None else "poly", requested="linear",
                                reason="no model choice recorded (a calibration from before pito chose models)")
        if not isinstance(model, ModelChoice):
            raise ValueError(f"model: expected a ModelChoice or None, got {type(model).__name__}")
        if (model.name == "poly") != (correction is not None):
            raise ValueError(f"model: {model.name!r} does not match the correction ({'none' if correction is None else 'poly'})")
        self.model = model
        if linear_fit is not None:
            lm, lo = (np.asarray(a, dtype=float) for a in linear_fit)
            if lm.shape != matrix.shape or lo.shape != (N_GAUGES,):
                raise ValueError(f"linear_fit: expected a matrix of shape {matrix.shape} and an offset of shape ({N_GAUGES},)")
            linear_fit = (lm, lo)
        self.linear_fit = linear_fit
        self._face_from_output = self._build_adjoints()
        self._apply = self._build_apply()
        self._apply_nl = self._build_apply_nl()
        self._apply_edge = self._build_apply_edge()
        self._apply_tangent = self._build_apply_tangent()
        self._apply_map = self._build_apply_map()

    def _build_adjoints(self) -> np.ndarray:
        """(6, 6, 6): each face's fitted output frame → its face frame (identity for ``face``)."""
        X = np.broadcast_to(np.eye(6), (6, 6, 6)).copy()
        if self.output_frame == "reference":
            T_ati_core = invert_pose(self.T_core_ati)
            for f in FACES:
                X[f - 1] = wrench_adjoint(T_ati_core @ self.core.face_pose(f))
        return X

    def _build_apply(self) -> np.ndarray:
        """(6, 6, 36) maps: counts → wrench on face i in face i's frame (zeros where no output)."""
        A = np.zeros((6, 6, N_GAUGES))
        for k, f in enumerate(self.output_faces):
            A[f - 1] = self._face_from_output[f - 1] @ self.matrix[6 * k : 6 * k + 6]
        return A

    def _build_apply_nl(self):
        """(6, 6, r) maps: correction features → wrench on face i in its frame (None for ``linear``)."""
        if self.correction is None:
            return None
        A = np.zeros((6, 6, self.correction.n_features))
        for k, f in enumerate(self.output_faces):
            A[f - 1] = self._face_from_output[f - 1] @ self.correction.coef[6 * k : 6 * k + 6]
        return A

    def _build_apply_edge(self):
        """(6, 6, 36) maps: counts beyond the correction's range → wrench on face i (None without an edge term)."""
        if self.correction is None or self.correction.beyond(np.zeros((1, N_GAUGES))) is None:
            return None
        A = np.zeros((6, 6, N_GAUGES))
        for k, f in enumerate(self.output_faces):
            A[f - 1] = self._face_from_output[f - 1] @ self.correction.edge_matrix[6 * k : 6 * k + 6]
        return A

    def _build_apply_map(self):
        """(6, 6, 36) maps: ``P x − x`` (``PolyCorrection.map_terms``) → wrench on face i (None without)."""
        c = self.correction
        if c is None or c.map_matrix is None:
            return None
        A = np.zeros((6, 6, N_GAUGES))
        for k, f in enumerate(self.output_faces):
            A[f - 1] = self._face_from_output[f - 1] @ c.map_matrix[6 * k : 6 * k + 6]
        return A

    def _build_apply_tangent(self):
        """``(features (6, 6, r), counts (6, 6, 36))`` maps of the correction's ``tangent`` rows alone (None without)."""
        c = self.correction
        if c is None or c.tangent is None or self._apply_edge is None:
            return None
        A, E = np.zeros((6, 6, c.n_features)), np.zeros((6, 6, N_GAUGES))
        for k, f in enumerate(self.output_faces):
            rows = c.tangent[6 * k : 6 * k + 6, None]
            A[f - 1] = self._face_from_output[f - 1] @ (c.coef[6 * k : 6 * k + 6] * rows)
            E[f - 1] = self._face_from_output[f - 1] @ (c.edge_matrix[6 * k : 6 * k + 6] * rows)
        return A, E

    # ------------------------------------------------------------------ use
    @property
    def has_output(self) -> np.ndarray:
        """(6,) bool: faces the calibration outputs."""
        m = np.zeros(6, dtype=bool)
        m[[f - 1 for f in self.output_faces]] = True
        return m

    @property
    def coverage(self) -> Coverage:
        """What this calibration measures: each face's axes and the net load (``meta["coverage"]``).

        Files written before pito recorded it get a coverage derived from ``meta["net_load"]``
        (``Coverage.known`` is then False).
        """
        return Coverage.from_meta(self.meta, self.has_output)

    def wrenches(self, counts, offset=None, *, return_cov: bool = False):
        """Wrench on each face in that face's frame (and its covariance).

        Parameters
        ----------
        counts : array-like, shape (N, 36) or (36,)
            Raw gauge counts.
        offset : array-like, shape (36,), optional
            Unloaded counts to subtract; default the calibration's own (fitted, or set by
            :meth:`tare`). With an explicit offset its own uncertainty is not included.
        return_cov : bool
            Also return each face's 6×6 covariance.

        Returns
        -------
        wrenches : ndarray, shape (N, 6, 6) (or (6, 6))
            ``[:, i-1, :]`` = ``[fx, fy, fz, tx, ty, tz]`` on face i in N and N·m,
            moment about face i's origin; NaN for faces the method does not output.
        cov : ndarray, shape (N, 6, 6, 6) (or (6, 6, 6)), with ``return_cov``
            ``cov[:, i-1]``: covariance of face i's wrench in its frame, N², N²·m, N²·m²
            — the calibration's own error (residuals and design of the fit) plus the gauge
            noise of the sample (and of the tare after :meth:`tare`), growing beyond the
            loads the correction was trained on (``_error.py``); NaN for faces
            without output. Raises ``ValueError`` if the calibration has no covariance
            (files of format version 1).
        """
        c = np.asarray(counts, dtype=float)
        single = c.ndim == 1
        c2 = np.atleast_2d(c)
        if c2.ndim != 2 or c2.shape[1] != N_GAUGES:
            raise ValueError(f"counts: expected shape (N, {N_GAUGES}), got {c.shape}")
        off = self.offset if offset is None else np.asarray(offset, dtype=float)
        if off.shape != (N_GAUGES,):
            raise ValueError(f"offset: expected shape ({N_GAUGES},), got {off.shape}")
        x = c2 - off
        n = x.shape[0]
        # The linear part by einsum: the same digits on every CPU (BLAS kernels differ by CPU and
        # tests/analysis/test_tables_golden.py pins the tables to the last digit); the correction's
        # wide feature maps by matrix products (BLAS), where einsum is 3-4x slower.
        W = np.einsum("fij,nj->nfi", self._apply, x)
        faded = ray = None
        if self._apply_nl is not None:
            ray = self.correction.ray(x)  # read by the correction's terms, its fade and the error bars beyond
            fade = self.correction.fade(x, ray)
            W_lin = W.copy() if fade is not None and np.any(fade < 1) else None
            phi, d, extra = self.correction.all_terms(x, ray)
            W += (phi @ self._apply_nl.reshape(6 * 6, -1).T).reshape(n, 6, 6)
            if d is not None and self._apply_edge is not None:  # beyond the fitted range, the linear fit's slope
                W += (d @ self._apply_edge.reshape(6 * 6, -1).T).reshape(n, 6, 6)
            if extra is not None and self._apply_tangent is not None:  # or, on tangent rows, the polynomial's
                A, E = self._apply_tangent
                W += (extra[0] @ A.reshape(6 * 6, -1).T + extra[1] @ E.reshape(6 * 6, -1).T).reshape(n, 6, 6)
            if self._apply_map is not None:  # corrected rows read P x in their linear part too
                W += (self.correction.map_terms(x) @ self._apply_map.reshape(6 * 6, -1).T).reshape(n, 6, 6)
            if W_lin is not None and self._apply_edge is not None:  # past the reach tested: fade to the linear fit
                k = np.flatnonzero((fade < 1).any(axis=1))
                W_full = W[k].copy()
                g = np.ones((k.size, 6, 6))  # each output row's share, on its face's axis (exact where the
                for j, f in enumerate(self.output_faces):  # output frame is the face's or its rows share one)
                    g[:, f - 1] = fade[k, 6 * j : 6 * j + 6]
                E = (x[k] @ self._apply_edge.reshape(6 * 6, -1).T).reshape(k.size, 6, 6)
                D = W[k] - W_lin[k]
                W[k] = W_lin[k] + g * D - (1.0 - g) * E
                for j, f in enumerate(self.output_faces):  # a face's axes mix its fitted rows: share on the rows
                    gj = fade[k, 6 * j : 6 * j + 6]
                    if self.output_frame == "face" or np.all(gj == gj[:, :1]):
                        continue
                    X = self._face_from_output[f - 1]
                    Dj = np.linalg.solve(X, D[:, f - 1].T).T
                    Ej = x[k] @ self.correction.edge_matrix[6 * j : 6 * j + 6].T
                    W[k, f - 1] = W_lin[k, f - 1] + (gj * Dj - (1.0 - gj) * Ej) @ X.T
                faded = (k, W_full - W[k])  # what the fade took off the correction: its error bar there
        W[:, ~self.has_output] = np.nan
        if not return_cov:
            return W[0] if single else W
        if self.covariance is None:
            raise ValueError("return_cov: this calibration has no covariance (written by an older pito, "
                             "format version 1); fit it again to get one")
        beyond = None
        if self.correction is not None and np.any(self.covariance.beyond_cov):
            own = get_method(self.method).inputs == "own"
            cols = [np.arange(6 * (f - 1), 6 * f) for f in self.output_faces] if own else [np.arange(N_GAUGES)]
            b = self.correction.beyond_sq(x, cols, ray)
            beyond = np.broadcast_to(b, (n, len(self.output_faces)))
        cov = self.covariance.face_covariances(c2, off, W, self._apply, self._face_from_output, self.output_faces,
                                               explicit_offset=offset is not None, beyond=beyond)
        if faded is not None:
            k, r = faded
            r = r[:, np.asarray(self.output_faces) - 1]
            cov[k[:, None], np.asarray(self.output_faces) - 1] += r[..., :, None] * r[..., None, :]
        return (W[0], cov[0]) if single else (W, cov)

    def linear_alternative(self) -> "Calibration":
        """The papers' linear fit of the same data (``self`` if that is the model in use).

        Its covariance is this calibration's (its error model is that of the chosen model).
        Raises ``ValueError`` for a ``poly`` calibration saved without it.
        """
        if self.correction is None:
            return self
        if self.linear_fit is None:
            raise ValueError("linear_fit: this calibration does not keep the papers' linear fit")
        m = ModelChoice(name="linear", requested="linear", cv_rmse=self.model.cv_rmse, cv_score=self.model.cv_score,
                        folds_won=self.model.folds_won, n_folds=self.model.n_folds, n_segments=self.model.n_segments,
                        reason="the papers' linear fit of the same data (switched from the polynomial model)")
        return Calibration(self.method, self.linear_fit[0], self.output_faces, self.output_frame, self.linear_fit[1],
                           self.core, self.T_core_ati, dict(self.meta, model="linear"),
                           covariance=self.covariance, model=m)

    def tare(self, counts_unloaded) -> "Calibration":
        """A copy whose offset is the mean of ``counts_unloaded (N, 36)`` (N ≥ 1).

        The covariance then includes the tare's own noise (gauge noise / N).
        """
        c = np.asarray(counts_unloaded, dtype=float)
        if c.ndim != 2 or c.shape[1] != N_GAUGES or c.shape[0] == 0:
            raise ValueError(f"counts_unloaded: expected shape (N, {N_GAUGES}) with N ≥ 1, got {c.shape}")
        return Calibration(
            self.method, self.matrix, self.output_faces, self.output_frame, c.mean(axis=0),
            self.core, self.T_core_ati, self.meta,
            covariance=None if self.covariance is None else self.covariance.retared(c.shape[0]),
            correction=self.correction, model=self.model,
            linear_fit=None if self.linear_fit is None else (self.linear_fit[0], c.mean(axis=0)),
        )

    @property
    def inverse_condition_number(self) -> float:
        """σmin/σmax of :attr:`matrix` as fitted: the affine part of the model in use. The PITO paper's
        Table I figure is the linear fit's, ``linear_alternative().inverse_condition_number``: a polynomial
        model's affine part is fitted per face and output group, so it can have full rank where the
        linear fit's rank (and ``meta["net_load"]``) says the data leave directions unmeasured."""
        s = np.linalg.svd(self.matrix, compute_uv=False)
        return float(s[-1] / s[0]) if s[0] > 0 else 0.0

    def face_inverse_condition_numbers(self) -> np.ndarray:
        """(6,) σmin/σmax of each face's 6 output rows (NaN where no output)."""
        out = np.full(6, np.nan)
        for k, f in enumerate(self.output_faces):
            s = np.linalg.svd(self.matrix[6 * k : 6 * k + 6], compute_uv=False)
            out[f - 1] = s[-1] / s[0] if s[0] > 0 else 0.0
        return out

    def __repr__(self) -> str:
        return (
            f"Calibration(method={self.method!r}, model={self.model.name!r}, matrix={self.matrix.shape[0]}×{N_GAUGES}, "
            f"faces={list(self.output_faces)}, frame={self.output_frame!r}, "
            f"1/cond={self.inverse_condition_number:.2e})"
        )

    # ------------------------------------------------------------------ files
    def save(self, path) -> None:
        """Write exactly ``path`` (HDF5, format ``pito-calibration`` v6; docs/file-formats.md)."""
        write_calibration(path, self)

    @classmethod
    def load(cls, path) -> "Calibration":
        """Read a calibration written by :meth:`save`."""
        return load_calibration(path)


def load_calibration(path) -> Calibration:
    """Read a calibration file written by :meth:`Calibration.save`.

    A wrong, truncated, corrupt or inconsistent file raises ``pito_core.io.FileFormatError``
    naming the file.
    """
    fields = read_calibration_fields(path)
    cov = fields.pop("covariance")
    linear_fit = None
    try:
        if fields["correction"] is not None:
            c = dict(fields["correction"])
            linear_fit = (c.pop("linear_matrix"), c.pop("linear_offset"))
            fields["correction"] = c
        corr = fields["correction"] and PolyCorrection(**fields["correction"])
        model = fields["model"] and ModelChoice.from_dict(fields["model"])
    except (ValueError, TypeError) as exc:
        raise FileFormatError(f"{path}: model: {exc}") from None
    try:
        if cov is not None:
            cov = CalibrationCovariance(groups=[CovarianceGroup(**g) for g in cov["groups"]], gauge_cov=cov["gauge_cov"],
                                        variance_coef=cov["variance_coef"], residual_corr=cov["residual_corr"],
                                        scale=cov["scale"], n_tare=cov["n_tare"], beyond_cov=cov.get("beyond_cov"))
    except ValueError as exc:
        raise FileFormatError(f"{path}: covariance: {exc}") from None
    try:
        return Calibration(
            fields["method"], fields["matrix"], fields["output_faces"], fields["output_frame"], fields["offset"],
            CubeCore(fields["core_edge"]), fields["T_core_ati"], fields["meta"], covariance=cov,
            correction=corr or None, model=model or None, linear_fit=linear_fit,
        )
    except ValueError as exc:
        raise FileFormatError(f"{path}: inconsistent calibration: {exc}") from None
