"""Fit and evaluate in one route: the wizard and ``pito calibrate`` give the same figures for the same data."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

from ..io import CalibrationSession
from ._calibration import Calibration
from ._evaluate import Evaluation, evaluate
from ._fit import RankDeficientError, calibrate
from ._validation import ValidationFigures, confirm_model, validation_figures

__all__ = ["FitResult", "fit_and_evaluate", "HOLDOUT", "HOLDOUT_BLOCK"]

#: Fraction of each session's samples held out of the fit to evaluate it.
HOLDOUT = 0.2
#: Samples per held-out block (`CalibrationSession.split`): a still capture of a few hundred
#: samples feeds both sides, so the fit keeps every loaded direction.
HOLDOUT_BLOCK = 50
#: What to do when the loads leave a direction unexcited (``fit_and_evaluate``'s ``rank_deficient``).
RANK_DEFICIENT = ("raise", "allow", "fallback")


@dataclass
class FitResult:
    """What :func:`fit_and_evaluate` gives.

    Attributes
    ----------
    calibration : Calibration
    heldout : Evaluation or None
        On the samples held out of every session, pooled (None with ``holdout=0``).
    heldout_by_session : list of Evaluation
        On each session's held-out samples, in the order of ``sessions`` (empty with ``holdout=0``;
        with one session, ``[heldout]``).
    validation : Evaluation or None
        On the validation passes (fresh loads, not fitted), pooled, if any was given; also in the
        calibration's ``meta["validation_pass"]`` (its ``to_dict()`` and ``n_sessions``).
    figures : ValidationFigures or None
        The validation passes' RMSE per loaded face with intervals (each face from the pass that
        loads it directly).
    note : str
        Why the fit is minimum-norm, if it is ("" otherwise).
    n_fit, n_heldout : int
        Samples fitted and held out.
    """

    calibration: Calibration
    heldout: Evaluation | None
    validation: Evaluation | None
    figures: ValidationFigures | None
    note: str
    n_fit: int
    n_heldout: int
    heldout_by_session: list = field(default_factory=list)

    @property
    def headline(self) -> Evaluation | None:
        """The figures to lead with: the validation pass's, else the held-out samples'."""
        return self.validation if self.validation is not None else self.heldout


def fit_and_evaluate(sessions, method: str, *, holdout: float = HOLDOUT, block: int = HOLDOUT_BLOCK, seed: int = 0,
                     model: str = "auto", validation=None, rank_deficient: str = "raise",
                     prior: str | None = None, block_size: int | None = None, progress=None) -> FitResult:
    """Split every session, fit ``method`` on the training parts, evaluate on the held-out parts and the validation pass.

    Parameters
    ----------
    sessions : CalibrationSession or sequence of them
        Every session is split the same way (``holdout``, in blocks of ``block`` samples, ``seed``).
    method : str
        A method of :data:`METHODS`.
    holdout : float
        Fraction held out of each session, in [0, 1); 0 fits everything and evaluates nothing.
    model : {"auto", "linear", "poly"}
        With ``"auto"`` and a validation pass, a correction the pass does not confirm gives way
        to the linear fit (:func:`confirm_model`).
    validation : CalibrationSession, sequence of them, or None
        Fresh loads not used in the fit: one pass per mount (the wizard: the main mount's and the
        second mount's), scored together; none (None or empty): the held-out samples only.
    rank_deficient : {"raise", "allow", "fallback"}
        Unexcited directions: raise :class:`RankDeficientError`, fit minimum-norm with a warning,
        or try the full fit and fall back to minimum-norm with ``note`` saying why.
    prior, block_size
        Passed to :func:`calibrate`.
    progress : callable or None
        ``progress(fraction, text)`` between the steps and during the fit; may raise to cancel.
    """
    if rank_deficient not in RANK_DEFICIENT:
        raise ValueError(f"rank_deficient: expected one of {RANK_DEFICIENT}, got {rank_deficient!r}")
    if not 0.0 <= holdout < 1.0:
        raise ValueError(f"holdout: expected a fraction in [0, 1), got {holdout!r}")
    sessions = [sessions] if isinstance(sessions, CalibrationSession) else list(sessions)
    if not sessions:
        raise ValueError("sessions: expected at least one session, got none")
    progress = progress or (lambda *_: None)
    progress(0.0, "splitting the samples")
    if holdout:
        pairs = [s.split(holdout, block=block, seed=seed) for s in sessions]
        train, test = [p[0] for p in pairs], [p[1] for p in pairs]
    else:
        train, test = sessions, []
    n_fit = sum(len(s) for s in train)
    options = {"model": model, "prior": prior, "allow_rank_deficient": rank_deficient == "allow"}
    if block_size is not None:
        options["block_size"] = block_size
    fit_progress = lambda done, total: progress(0.1 + 0.55 * done / max(total, 1),  # noqa: E731
                                                f"fitting {method}: {done} / {total} samples")
    progress(0.1, f"fitting {method} on {n_fit} samples")
    note = ""
    try:
        cal = calibrate(train, method, progress=fit_progress, **options)
    except RankDeficientError as exc:
        if rank_deficient != "fallback":
            raise
        options["allow_rank_deficient"] = True
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cal = calibrate(train, method, progress=fit_progress, **options)
        note = f"minimum-norm fit — {exc}"
    figures = checked = None
    validation = [] if validation is None else [validation] if isinstance(validation, CalibrationSession) \
        else list(validation)
    if validation:
        progress(0.7, f"validating on {sum(len(s) for s in validation)} fresh samples")
        if model == "auto":
            cal, figures = confirm_model(cal, validation, seed=seed, sessions=train, fit_options=options)
        else:
            figures = validation_figures(cal, validation, seed=seed)
        checked = evaluate(cal, validation)
        cal.meta["validation_pass"] = {**checked.to_dict(), "n_sessions": len(validation)}
    heldout, by_session = None, []
    if test:
        progress(0.8, f"evaluating on {sum(len(s) for s in test)} held-out samples")
        heldout = evaluate(cal, test)
        by_session = [heldout] if len(test) == 1 else [evaluate(cal, s) for s in test]
    progress(1.0, "done")
    return FitResult(cal, heldout, checked, figures, note, n_fit, sum(len(s) for s in test), by_session)
