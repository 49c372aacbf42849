"""The five calibration methods of the two seed papers, as a table of descriptions.

One least-squares core (``_fit.py``) reads these rows; nothing else differs between
the methods.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["MethodSpec", "METHODS", "get_method"]


@dataclass(frozen=True)
class MethodSpec:
    """What distinguishes one calibration method from another.

    Attributes
    ----------
    name : str
        Method name used in every API and file.
    paper : str
        Where it comes from.
    flanges : tuple of str
        Mounts the sessions may use (``frame``, ``frame_hole``, ``face``).
    inputs : {"own", "all"}
        Gauges each face's rows are fitted from: its own 6, or all 36.
    outputs : {"loaded", "free", "all"}
        Faces the matrix outputs: every face that carried load in the data
        (``loaded``), the faces other than the connected face (``free``), or all six.
    output_frame : {"face", "reference"}
        Frame the fitted rows give wrenches in: each face's own frame, or the
        reference frame S_A (converted to face frames by ``Calibration.wrenches``).
    load_connected : bool
        Whether the connected face is loaded directly in the protocol.
    mixed_mounts : bool
        Whether sessions from several connected faces may be combined in one fit.
    summary : str
        One sentence for operators: flange, faces loaded, result.
    """

    name: str
    paper: str
    flanges: tuple[str, ...]
    inputs: str
    outputs: str
    output_frame: str
    load_connected: bool
    mixed_mounts: bool
    summary: str


METHODS: dict[str, MethodSpec] = {
    m.name: m
    for m in (
        MethodSpec(
            name="face_to_face",
            paper="multi-touch calibration, II-A",
            flanges=("frame", "frame_hole", "face"),
            inputs="own",
            outputs="loaded",
            output_frame="face",
            load_connected=True,
            mixed_mounts=True,
            summary=(
                "Any flange; load each face in turn; six independent 6×6 matrices, each face's "
                "wrench from its own 6 gauges (inter-face coupling is not modelled)."
            ),
        ),
        MethodSpec(
            name="quasi_total",
            paper="multi-touch calibration, II-B",
            flanges=("frame",),
            inputs="all",
            outputs="free",
            output_frame="face",
            load_connected=False,
            mixed_mounts=False,
            summary=(
                "Flange on the core frame (type 1); load the 5 free faces; a 30×36 matrix giving "
                "the free faces' wrenches from all 36 gauges (the connected face has no output)."
            ),
        ),
        MethodSpec(
            name="total",
            paper="multi-touch calibration, II-C",
            flanges=("face",),
            inputs="all",
            outputs="all",
            output_frame="face",
            load_connected=True,
            mixed_mounts=True,
            summary=(
                "Flange on a face (type 3); load every face; a 36×36 matrix, the connected face's "
                "rows fitted from its own direct loads and the reactions −W of the others (eq. 6)."
            ),
        ),
        MethodSpec(
            name="loaded_frame",
            paper="PITO paper, III-A",
            flanges=("frame_hole",),
            inputs="all",
            outputs="all",
            output_frame="reference",
            load_connected=True,
            mixed_mounts=False,
            summary=(
                "Flange with an access hole on the core frame (type 2); load all 6 faces; a 36×36 "
                "matrix fitted in the reference frame S_A, mapped to face frames when applied."
            ),
        ),
        MethodSpec(
            name="unloaded_frame",
            paper="PITO paper, III-B",
            flanges=("face",),
            inputs="all",
            outputs="all",
            output_frame="face",
            load_connected=False,
            mixed_mounts=False,
            summary=(
                "Flange on a face (type 3); load the 5 free faces; a 36×36 matrix in face frames "
                "(adjoint maps), the connected face fitted to the reaction −ΣW."
            ),
        ),
    )
}


def get_method(method) -> MethodSpec:
    """The :class:`MethodSpec` named ``method`` (or ``method`` itself if already one)."""
    if isinstance(method, MethodSpec):
        return method
    try:
        return METHODS[method]
    except (KeyError, TypeError):
        raise ValueError(f"method: expected one of {sorted(METHODS)}, got {method!r}") from None
