"""The calibration file: HDF5, format ``pito-calibration``, version 6 (reads 6 only: 0.1.0 is unreleased).

Layout (docs/file-formats.md)::

    /             attrs: format="pito-calibration", version=6, writer, method, output_frame,
                         output_faces [..], core_edge (m), meta (JSON text),
                         model (JSON text: which model and its cross-validated figures)
    /matrix       (6·F, 36) float64: counts → N, N·m
    /offset       (36,) float64 counts
    /T_core_ati   (4, 4) float64
    /covariance   group (optional: a calibration built without one), attrs: n_groups, n_tare (-1: fitted offset),
                  scale (factor on standard deviations that makes the training coverage nominal)
        gauge_cov         (36, 36) float64 counts²: gauge noise at rest
        g{k}_inputs       (m,) int64 gauge columns of least-squares problem k
        g{k}_rows         (q,) int64 rows of /matrix it fitted
        g{k}_design_pinv  (n_int+m, n_int+m) float64 (XᵀX)⁺ of its design [offset columns | counts − center]
        g{k}_residual_cov (q, q) float64 residual covariance (N², N²·m, N²·m²), attrs: dof
        g{k}_center       (m,) float64 counts
        g{k}_weights      (n_int,) float64
        g{k}_carry_pinv   (q/6, n_int+m, n_int+m) float64, optional: per output face P G_c P, G_c the Gram of the
                          design rows where the face carries (per counts²)
        g{k}_carry_cov    (q/6, 2, 6, 6) float64, optional (with carry_pinv): per output face the residual
                          covariance where it carries / carries nothing (output frame; N², N²·m, N²·m²)
        variance_coef     (6F, 4) float64: each face axis's error variance on [1, q, q², q_other] (face frames)
        residual_corr     (F, 6, 6) float64: residual correlation between a face's six axes
        beyond_cov        (F, 6, 6) float64, optional: a face wrench's error covariance (face frames) per unit of
                          ‖(counts beyond the correction's trained box) / scale‖², from held-out extrapolation
    /correction   group (model "poly" only): the polynomial correction
        scale             (36,) float64 counts per unit of u = (counts − offset) / scale
        pairs             (P, 2) int64 gauge pairs of the products u_i u_j
        cubes             (Q,) int64 gauges of the cubes u_i³
        coef              (6·F, P + Q) float64: N, N·m per feature, rows as /matrix
        linear_matrix     (6·F, 36) float64, linear_offset (36,): the papers' linear fit of the same data
        lower, upper      (36,) float64: range of u fitted; a sample beyond it (and beyond the domain's box)
                          is drawn back along its ray (_poly.py)
        edge_matrix       (6·F, 36) float64: the corrected slopes less the linear fit's, used beyond the range
        domain            (d, 36) float64, optional: a second box's coordinates (rows of the linear fit), N, N·m
                          per count; domain_lower, domain_upper (d,): its range in training
        input_map         (36, 36) float64, optional: the counts the correction reads, P x (face_to_face)
        tangent           (6·F,) bool, optional: rows continued beyond the range along the polynomial's tangent
        map_matrix        (6·F, 36) float64, optional: slopes of P x − x (the linear fit's corrected rows)
        map_lower, map_upper (36,) float64, optional: the trained range of P x − x, which map_matrix leaves out
"""

from __future__ import annotations

import os

import h5py
import numpy as np

from ._hdf5 import FileFormatError, checked_dataset, json_attr, open_checked, read_json_attr, require, seal, verify, write_header

__all__ = ["write_calibration", "read_calibration_fields", "CALIBRATION_FORMAT", "CALIBRATION_VERSION"]

CALIBRATION_FORMAT = "pito-calibration"
CALIBRATION_VERSION = 6
#: Versions this pito reads (6: the correction's edge_matrix; no file of an older version exists
#: outside the tests, and 0.1.0 is unreleased).
CALIBRATION_READ_VERSIONS = {6}
_CORRECTION_FIELDS = ("scale", "pairs", "cubes", "coef")
#: The range the correction was fitted on, and its slopes beyond.
_CORRECTION_RANGE = ("lower", "upper", "edge_matrix", "domain", "domain_lower", "domain_upper",
                     "input_map", "tangent", "map_matrix", "map_lower", "map_upper", "edge_mapped", "reach")
_GROUP_FIELDS = ("inputs", "rows", "design_pinv", "residual_cov", "center", "weights")
#: Optional (files before 2026-12-07 have none): the coefficients' covariance as a sandwich.
_GROUP_SANDWICH = ("carry_pinv", "carry_cov")


def write_calibration(path, cal) -> None:
    """Write ``cal`` to exactly ``path`` (atomically: a temporary file, then rename)."""
    tmp = f"{os.fspath(path)}.partial"
    with h5py.File(tmp, "w") as f:
        write_header(f, CALIBRATION_FORMAT, CALIBRATION_VERSION)
        f.attrs["method"] = cal.method
        f.attrs["output_frame"] = cal.output_frame
        f.attrs["output_faces"] = np.asarray(cal.output_faces, dtype=np.int64)
        f.attrs["core_edge"] = cal.core.edge
        f.attrs["meta"] = json_attr(cal.meta)
        checked_dataset(f, "matrix", data=cal.matrix)
        checked_dataset(f, "offset", data=cal.offset)
        checked_dataset(f, "T_core_ati", data=cal.T_core_ati)
        f.attrs["model"] = json_attr(cal.model.to_dict())
        if cal.correction is not None:
            g = f.create_group("correction")
            for name in _CORRECTION_FIELDS + _CORRECTION_RANGE:
                if getattr(cal.correction, name, None) is not None:
                    checked_dataset(g, name, data=getattr(cal.correction, name))
            checked_dataset(g, "linear_matrix", data=cal.linear_fit[0])
            checked_dataset(g, "linear_offset", data=cal.linear_fit[1])
        cov = getattr(cal, "covariance", None)
        if cov is not None:
            g = f.create_group("covariance")
            g.attrs["n_groups"] = len(cov.groups)
            g.attrs["n_tare"] = -1 if cov.n_tare is None else int(cov.n_tare)
            checked_dataset(g, "gauge_cov", data=cov.gauge_cov)
            g.attrs["scale"] = float(cov.scale)
            for k, grp in enumerate(cov.groups):
                for name in _GROUP_FIELDS:
                    checked_dataset(g, f"g{k}_{name}", data=getattr(grp, name))
                g[f"g{k}_residual_cov"].attrs["dof"] = int(grp.dof)
                for name in _GROUP_SANDWICH:
                    if getattr(grp, name, None) is not None:
                        checked_dataset(g, f"g{k}_{name}", data=getattr(grp, name))
            checked_dataset(g, "variance_coef", data=cov.variance_coef)
            checked_dataset(g, "residual_corr", data=cov.residual_corr)
            checked_dataset(g, "beyond_cov", data=cov.beyond_cov)
        seal(f)  # SHA-256 manifest of every dataset and attribute (last: covers everything above)
    os.replace(tmp, path)


def read_calibration_fields(path) -> dict:
    """Read a calibration file into plain fields; a wrong, truncated or corrupt file raises ``FileFormatError``.

    Returns the keyword arguments of ``pito_core.calibration.Calibration`` (``method``,
    ``matrix`` (M, 36), ``output_faces``, ``output_frame``, ``offset`` (36,) counts,
    ``core_edge`` m, ``T_core_ati`` (4, 4), ``meta``), ``model`` (dict or None), ``correction``
    (dict of ``scale``, ``pairs``, ``cubes``, ``coef``, or None) and ``covariance``: ``None`` or a dict
    (``groups``: list of dicts, ``gauge_cov``, ``n_tare``, ``scale``, ``variance_coef``, ``residual_corr``,
    ``beyond_cov`` or None).
    The objects are built by ``pito_core.calibration.load_calibration`` (io never imports calibration).
    """
    with open_checked(path, CALIBRATION_FORMAT, CALIBRATION_READ_VERSIONS) as f:
        verify(f, path)  # ChecksumError naming the dataset; a warning for files without checksums
        try:
            attrs = {k: f.attrs[k] for k in ("method", "output_frame", "output_faces", "core_edge")}
        except KeyError as exc:
            raise FileFormatError(f"{path}: missing attribute {exc}") from None
        try:
            matrix = np.asarray(require(f, "matrix", path)[()])
            offset = np.asarray(require(f, "offset", path)[()])
            T = np.asarray(require(f, "T_core_ati", path)[()])
            covariance = _read_covariance(f, path) if "covariance" in f else None
            correction = ({name: np.asarray(require(f["correction"], name, path)[()])
                           for name in _CORRECTION_FIELDS + ("linear_matrix", "linear_offset")
                           + tuple(n for n in _CORRECTION_RANGE if n in f["correction"])}
                          if "correction" in f else None)
        except OSError as exc:
            raise FileFormatError(f"{path}: data could not be read (truncated or corrupt?): {exc}") from None
        meta = read_json_attr(f, "meta", path)
        model = read_json_attr(f, "model", path) if "model" in f.attrs else None
    dec = lambda v: v.decode() if isinstance(v, bytes) else str(v)  # noqa: E731
    return {
        "method": dec(attrs["method"]), "matrix": matrix, "output_faces": [int(v) for v in attrs["output_faces"]],
        "output_frame": dec(attrs["output_frame"]), "offset": offset, "core_edge": float(attrs["core_edge"]),
        "T_core_ati": T, "meta": meta, "covariance": covariance, "correction": correction, "model": model,
    }


def _read_covariance(f, path) -> dict:
    g = f["covariance"]
    try:
        n_groups, n_tare, scale = int(g.attrs["n_groups"]), int(g.attrs["n_tare"]), float(g.attrs["scale"])
    except KeyError as exc:
        raise FileFormatError(f"{path}: covariance: missing attribute {exc}") from None
    groups = []
    for k in range(n_groups):
        fields = {name: np.asarray(require(g, f"g{k}_{name}", path)[()]) for name in _GROUP_FIELDS}
        fields.update({name: np.asarray(g[f"g{k}_{name}"][()]) for name in _GROUP_SANDWICH if f"g{k}_{name}" in g})
        groups.append({**fields, "dof": int(g[f"g{k}_residual_cov"].attrs.get("dof", 0))})
    return {
        "groups": groups,
        "gauge_cov": np.asarray(require(g, "gauge_cov", path)[()]),
        "n_tare": None if n_tare < 0 else n_tare,
        "scale": scale,
        "variance_coef": np.asarray(require(g, "variance_coef", path)[()]),
        "residual_corr": np.asarray(require(g, "residual_corr", path)[()]),
        "beyond_cov": np.asarray(g["beyond_cov"][()]) if "beyond_cov" in g else None,
    }
