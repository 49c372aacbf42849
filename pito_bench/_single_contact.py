"""Benchmark of the single-contact test: false alarms, detection and the indistinguishable share.

Per patch kind (the contact benchmark's plane, sphere, ellipsoid and 5,000-facet mesh, each
given a boundary) and simulated touches:

- *single touches*: one fingertip inside its limits (random point on the patch, force
  1–10 N within the friction cone, torsion within the elliptic limit surface);
- *two-finger touches*: two such fingertips at random places (≥ 5 mm apart), force ratio
  0.1–1, each with its own tangential load and torsion.

Every measured wrench carries the calibration's noise: Gaussian gauge noise (the benchmark's
``mid`` level) plus a calibration error ``E w`` (1 % relative, a fresh draw per touch, scaled
per axis), and the test gets that covariance, as ``Calibration.wrenches(return_cov=True)``
gives it. The false-alarm rate is the share of single touches flagged. For two-finger
touches the separation ``D`` is how far the best single-contact explanation (the
soft-finger solution of the noise-free wrench) breaks its limits, in standard deviations
of each limit's margin measured by Monte Carlo over noisy repeats (robust σ): ``D ≤ 0`` means
one fingertip produces that wrench exactly (no method can tell), ``D > 3`` breaks a limit by
more than the noise. Detection is the share flagged, per separation bin.
"""

from __future__ import annotations

import warnings

import numpy as np

from pito_core.contact import Patch, PatchBoundary, reason_names, solve

from ._contact import make_surface, sample_contacts

__all__ = ["SEPARATION_BINS", "CAL_ERROR", "task_single_contact", "limit_margins", "two_finger_touches",
           "single_table_rows", "plot_single"]

#: Separation bins (standard deviations) of the detection table.
SEPARATION_BINS = (0.0, 1.0, 2.0, 3.0, 5.0, np.inf)
#: Relative calibration error (dimensionless) of the simulated calibration.
CAL_ERROR = 0.01
#: Axis scales (N, N·m) relating force and moment errors (a 20 mm moment arm).
_SCALE = np.array([1.0, 1.0, 1.0, 0.02, 0.02, 0.02])


def bench_patch(kind: str):
    """The contact benchmark's surface of ``kind`` with a boundary: a ``Patch``."""
    surface = make_surface(kind)
    if kind in ("plane", "mesh"):
        boundary = PatchBoundary("rectangle", size=[0.04, 0.04])
    else:
        boundary = PatchBoundary(None, z_min=0.0)
    return Patch(surface, boundary, name=f"bench_{kind}")


def _cal_noise(w, sigma, rng):
    """Noisy wrenches and their covariances ``(n, 6, 6)``: gauge noise + calibration error."""
    n = len(w)
    load = np.sum((w / _SCALE) ** 2, axis=1)
    var = sigma**2 + (CAL_ERROR * _SCALE) ** 2 * load[:, None]
    cov = np.zeros((n, 6, 6))
    cov[:, np.arange(6), np.arange(6)] = var
    E = rng.normal(size=(n, 6, 6)) * CAL_ERROR * _SCALE[None, :, None] / _SCALE[None, None, :]
    return w + np.einsum("nij,nj->ni", E, w) + rng.normal(size=(n, 6)) * sigma, cov


def _on_patch(patch, n, rng, inset=0.002):
    """Random points ``(n, 3)`` on the patch (at least ``inset`` m inside its edge) and normals."""
    c = np.empty((0, 3))
    nrm = np.empty((0, 3))
    while len(c) < n:
        ci, ni, _, _ = sample_contacts(patch.surface, 2 * n, "soft", rng)
        keep = patch.boundary.margin(ci) > inset
        c, nrm = np.r_[c, ci[keep]], np.r_[nrm, ni[keep]]
    return c[:n], nrm[:n]


def _fingertip(nrm, rng, mu, e):
    """Force (1–10 N) within the friction cone and torsion within the elliptic limit."""
    n = len(nrm)
    a = np.where(np.abs(nrm[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t1 = np.cross(nrm, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(nrm, t1)
    fn = rng.uniform(1.0, 10.0, n)
    use = rng.uniform(0.0, 1.0, (n, 2))  # shares of the limit surface used by shear and twist
    shear = mu * fn * use[:, 0]
    phi = rng.uniform(0, 2 * np.pi, n)
    f = -fn[:, None] * nrm + shear[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2)
    tmax = mu * e * fn * np.sqrt(1.0 - use[:, 0] ** 2)
    tau = tmax * use[:, 1] * rng.choice([-1.0, 1.0], n)
    return f, tau


def _wrench(c, nrm, f, tau):
    return np.c_[f, np.cross(c, f) + tau[:, None] * nrm]


def two_finger_touches(patch, n, rng):
    """Noise-free wrenches ``(n, 6)`` of two fingertips on the patch (see module docstring)."""
    c1, n1 = _on_patch(patch, n, rng)
    c2, n2 = _on_patch(patch, n, rng)
    far = np.linalg.norm(c1 - c2, axis=1) >= 0.005
    while not far.all():
        c2[~far], n2[~far] = _on_patch(patch, int((~far).sum()), rng)
        far = np.linalg.norm(c1 - c2, axis=1) >= 0.005
    f1, t1 = _fingertip(n1, rng, patch.mu, patch.torsion_radius)
    f2, t2 = _fingertip(n2, rng, patch.mu, patch.torsion_radius)
    ratio = rng.uniform(0.1, 1.0, n)
    return _wrench(c1, n1, f1, t1) + ratio[:, None] * _wrench(c2, n2, f2, t2)


def limit_margins(patch, est):
    """Margins ``(n, 3)`` of the estimates' single-contact limits: pushing (N), friction (N), edge (m)."""
    f, n, tau = est.force, est.normal, est.torsion
    fn = -np.einsum("ij,ij->i", f, n)
    ft = np.linalg.norm(f + fn[:, None] * n, axis=1)
    fric = patch.mu * fn - np.hypot(ft, tau / patch.torsion_radius)
    return np.c_[fn, fric, patch.boundary.margin(est.point)]


def separation(patch, w0, cov, rng, repeats=100):
    """``D (n,)``: how many σ the best single-contact explanation of ``w0`` breaks a limit by."""
    n = len(w0)
    keep = dict(force_threshold=0.0)
    est0 = solve(patch.surface, w0, **keep)
    g0 = limit_margins(patch, est0)
    wr = np.repeat(w0, repeats, axis=0)
    L = np.linalg.cholesky(np.repeat(cov, repeats, axis=0))
    noisy = wr + np.einsum("nij,nj->ni", L, rng.normal(size=wr.shape))
    g = limit_margins(patch, solve(patch.surface, noisy, **keep)).reshape(n, repeats, 3)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows: no solution in any repeat
        q = np.nanpercentile(g, [15.87, 84.13], axis=1)
        sig = 0.5 * (q[1] - q[0])
        D = np.nanmax(np.where(sig > 0, -g0 / sig, np.where(g0 < 0, np.inf, -np.inf)), axis=1)
    return np.where(np.isfinite(est0.point).all(axis=1), D, np.inf)


def task_single_contact(n_single=4000, n_two=2000, repeats=100, surfaces=("plane", "sphere", "ellipsoid", "mesh"),
                        sigma=(0.02, 2e-4), seed=1) -> dict:
    """False alarms, detection per separation bin and the indistinguishable share per patch kind."""
    rng = np.random.default_rng(seed)
    sig = np.array([sigma[0]] * 3 + [sigma[1]] * 3)
    rows = []
    for kind in surfaces:
        patch = bench_patch(kind)
        c, nrm = _on_patch(patch, n_single, rng)
        f, tau = _fingertip(nrm, rng, patch.mu, patch.torsion_radius)
        w, cov = _cal_noise(_wrench(c, nrm, f, tau), sig, rng)
        fa = 1.0 - solve(patch, w, wrench_cov=cov).single_contact.mean()
        wp, covp = _cal_noise(_wrench(c, nrm, f, 0 * tau), sig, rng)
        fa_pc = 1.0 - solve(patch, wp, wrench_cov=covp, point_contact=True).single_contact.mean()
        w0 = two_finger_touches(patch, n_two, rng)
        w2, cov2 = _cal_noise(w0, sig, rng)
        D = separation(patch, w0, cov2, rng, repeats)
        est = solve(patch, w2, wrench_cov=cov2)
        flagged = ~est.single_contact
        bins = []
        for lo, hi in zip(SEPARATION_BINS[:-1], SEPARATION_BINS[1:]):
            m = (D > lo) & (D <= hi)
            bins.append({"lo": lo, "hi": hi if np.isfinite(hi) else None, "n": int(m.sum()),
                         "detected": float(flagged[m].mean()) if m.any() else float("nan")})
        beyond = D > 3.0
        if kind == "plane":
            sample = _limit_sample(patch, solve(patch.surface, w0, force_threshold=0.0), D, flagged)
        names, counts = np.unique(reason_names(est.single_contact_reason[flagged]), return_counts=True)
        rows.append({
            "surface": kind, "n_single": n_single, "n_two": n_two,
            "false_alarm": float(fa), "false_alarm_point_contact": float(fa_pc),
            "indistinguishable": float(np.mean(D <= 0.0)), "within_noise": float(np.mean((D > 0.0) & (D <= 3.0))),
            "detected_beyond_3sigma": float(flagged[beyond].mean()) if beyond.any() else float("nan"),
            "flagged_two_finger": float(flagged.mean()),
            "flag_at_or_below_0": float(flagged[D <= 0].mean()) if (D <= 0).any() else float("nan"),
            "bins": bins, "reasons": {str(k): int(v) for k, v in zip(names, counts)},
        })
    return {"rows": rows, "sigma_force_N": sigma[0], "sigma_moment_Nm": sigma[1], "calibration_error": CAL_ERROR,
            "separation_bins": [float(b) if np.isfinite(b) else None for b in SEPARATION_BINS],
            "plane_sample": sample if "plane" in surfaces else None}


def _limit_sample(patch, est0, D, flagged, k=600) -> dict:
    """Where the plane's two-finger touches sit on the limit surface (for the figure), first ``k``."""
    f, n, tau = est0.force[:k], est0.normal[:k], est0.torsion[:k]
    fn = -np.einsum("ij,ij->i", f, n)
    ft = np.linalg.norm(f + fn[:, None] * n, axis=1)
    lim = patch.mu * fn
    return {"shear": (ft / lim).tolist(), "twist": (np.abs(tau) / (patch.torsion_radius * lim)).tolist(),
            "D": np.where(np.isfinite(D[:k]), D[:k], 99.0).tolist(), "flagged": flagged[:k].astype(int).tolist()}


def single_table_rows(single: dict) -> tuple[list, list]:
    """Header and rows of the report's single-contact table (percentages)."""
    bins = single["separation_bins"]
    labels = [f"D {lo:g}–{hi:g}" if hi is not None else f"D > {lo:g}" for lo, hi in zip(bins[:-1], bins[1:])]
    header = (["patch", "false alarms (%)", "false alarms point contact (%)", "indistinguishable D ≤ 0 (%)",
               "within noise 0 < D ≤ 3 (%)", "detected D > 3 (%)"] + [f"detected {x} (%) [n]" for x in labels])
    rows = []
    for r in single["rows"]:
        pct = lambda x: "—" if x is None or not np.isfinite(x) else f"{100 * x:.1f}"  # noqa: E731
        rows.append([r["surface"], pct(r["false_alarm"]), pct(r["false_alarm_point_contact"]),
                     pct(r["indistinguishable"]), pct(r["within_noise"]), pct(r["detected_beyond_3sigma"])]
                    + [f"{pct(b['detected'])} [{b['n']}]" for b in r["bins"]])
    return header, rows


def plot_single(single: dict, axes, tag: str = "") -> None:
    """The figure of ``docs/contact.md``: detection against separation, and the plane's limit surface."""
    ax = axes[0]
    bins = single["separation_bins"]
    mids = [0.5 * (lo + hi) if hi is not None else lo + 1.5 for lo, hi in zip(bins[:-1], bins[1:])]
    for j, r in enumerate(single["rows"]):
        det = [np.nan if b["detected"] is None else b["detected"] for b in r["bins"]]
        ax.plot(mids, 100 * np.asarray(det, float), "o-", color=f"C{j}",
                label=f"{r['surface']} (false alarms {100 * r['false_alarm']:.1f} %)")
    ax.axhline(90, color="k", ls=":", lw=0.8)
    ax.axvline(3, color="k", ls="--", lw=0.8)
    ax.set_xlabel("separation D of the best single-contact explanation (σ of its margin)")
    ax.set_ylabel("two-finger touches flagged (%)")
    ax.set_ylim(0, 102)
    ax.set_title("Detection of two-finger touches, simulated" + tag)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    s = single.get("plane_sample")
    if not s:
        return
    ax = axes[1]
    sh, tw, fl = (np.asarray(s[k], float) for k in ("shear", "twist", "flagged"))
    ax.scatter(sh[fl == 0], tw[fl == 0], s=8, c="C2", label="plausible single contact")
    ax.scatter(sh[fl == 1], tw[fl == 1], s=8, c="C3", marker="x", label="flagged")
    t = np.linspace(0, np.pi / 2, 100)
    ax.plot(np.cos(t), np.sin(t), "k-", lw=1, label="limit surface (μ, torsion radius)")
    ax.set_xlabel("|f_t| / (μ f_n) (1)")
    ax.set_ylabel("|τ| / (μ e f_n) (1)")
    ax.set_xlim(0, 2)
    ax.set_ylim(0, 3)
    ax.set_title("Two fingers on the flat patch: their single-contact\nexplanation on the limit surface, simulated" + tag)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
