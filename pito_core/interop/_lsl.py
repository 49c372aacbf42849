"""Lab Streaming Layer outlets ``pito-wrenches`` and ``pito-contacts`` (pylsl; docs/interop.md, "LSL").

- ``pito-wrenches``, type ``Force``, 36 float32 channels at the cube's rate: face i
  (1..6) gives channels ``6(i−1) .. 6(i−1)+5`` = ``F{i}_fx F{i}_fy F{i}_fz F{i}_tx F{i}_ty F{i}_tz``
  in face i's own frame, N and N·m.
- ``pito-contacts``, type ``Contact``, 72 float32 channels at the same rate: face i gives
  12 channels ``C{i}_px py pz`` (m, core frame), ``nx ny nz`` (unit), ``fx fy fz`` (N, core
  frame), ``torsion`` (N·m), ``valid`` (0/1) — NaN where no contact — and ``single`` (1: one
  fingertip can produce the face's wrench, 0: it cannot or there is no force; a valid contact
  with ``single`` 0 is flagged; ``ContactEstimate.single_contact``).
- ``desc``: ``channels/channel`` (``label``, ``unit``, ``type``, ``face``), ``acquisition``
  (manufacturer, model), ``reference_frame``, ``calibration`` (method, date, hash, source),
  ``assembly`` (name, patch per face), ``simulated``.

Timestamps: the cube's device clock (``time_us``, unwrapped; the one time base of pito's
exports), strictly increasing, a dropped frame a gap, placed on the LSL clock once: the first
sample published gets its pairing-rule time (device clock mapped onto the host's
``time.monotonic``, :mod:`pito_core.devices._clock`) plus ``local_clock() − time.monotonic()``
(both CLOCK_MONOTONIC on Linux, so ~0), every later one that plus its device time since: LSL
time of the sample's *acquisition*, not of its push.

Inside a network namespace with loopback only, liblsl logs "No local network interface
addresses found": expected there (its streams still resolve on 127.0.0.1).

Safety: liblsl multicasts to find peers unless configured; run under a machine-only
``LSLAPICFG`` (:func:`machine_only_config`) — the tests run inside a private network namespace.
"""

from __future__ import annotations

import ipaddress
import os
import time
from pathlib import Path

import numpy as np

from ._conventions import (
    CONTACT_CHANNEL_COUNT,
    CONTACT_CHANNELS,
    CONTACT_STREAM,
    CONTACT_TYPE,
    CORE_FRAME,
    FACE_FRAME,
    WRENCH_CHANNELS,
    WRENCH_STREAM,
    WRENCH_TYPE,
)
from ._provenance import assembly_record as _asm, calibration_record as _cal

__all__ = ["LslPublisher", "lsl_stream_infos", "wrench_samples", "contact_samples", "machine_only_config",
           "MACHINE_ONLY_CONFIG", "listening_sockets"]

#: liblsl configuration that keeps every packet on this machine (write it to a file, point LSLAPICFG at it).
MACHINE_ONLY_CONFIG = """\
; pito: Lab Streaming Layer restricted to this machine (docs/interop.md).
; Keys as liblsl's api_config reads them: [ports] IPv6, [multicast] ResolveScope and the
; per-scope address sets, AddressesOverride/TTLOverride, ListenAddress, [lab] KnownPeers.
[ports]
IPv6 = disable
[multicast]
ResolveScope = machine
ListenAddress = 127.0.0.1
MachineAddresses = {127.0.0.1}
LinkAddresses = {}
SiteAddresses = {}
OrganizationAddresses = {}
GlobalAddresses = {}
AddressesOverride = {127.0.0.1}
TTLOverride = 0
[lab]
KnownPeers = {127.0.0.1}
"""


def machine_only_config(path) -> str:
    """Write :data:`MACHINE_ONLY_CONFIG` to ``path``; returns the path (for ``LSLAPICFG``)."""
    Path(path).write_text(MACHINE_ONLY_CONFIG)
    return str(Path(path).resolve())


def listening_sockets() -> list[str] | None:
    """This process's listening TCP and bound UDP sockets, e.g. ``["TCP 0.0.0.0:16572", "UDP 127.0.0.1:16571"]``.

    Read from ``/proc`` (Linux: the socket inodes of ``/proc/self/fd`` matched in ``/proc/self/net``);
    None where that is not available. With pito's machine-only config liblsl answers discovery on
    127.0.0.1 only, but binds each outlet's TCP and UDP data ports to every interface (liblsl has
    no setting for their address): this says exactly what listens where.
    """
    fd_dir, net = Path("/proc/self/fd"), Path("/proc/self/net")
    if not fd_dir.is_dir() or not net.is_dir():
        return None
    inodes = set()
    for fd in fd_dir.iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = []
    for proto, kind, listen_state in (("tcp", "TCP", "0A"), ("udp", "UDP", "07"), ("tcp6", "TCP", "0A"),
                                      ("udp6", "UDP", "07")):
        try:
            lines = (net / proto).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            f = line.split()
            if len(f) > 9 and f[9] in inodes and f[3] == listen_state:
                found.append(f"{kind} {_address(f[1])}")
    return sorted(set(found))


def _address(hex_addr: str) -> str:
    """``0100007F:407C`` (``/proc/net/tcp``, little-endian IPv4 or IPv6) → ``127.0.0.1:16508``."""
    host, port = hex_addr.split(":")
    raw = bytes.fromhex(host)
    if len(raw) == 4:
        ip = ".".join(str(b) for b in raw[::-1])
    else:
        words = [raw[k:k + 4][::-1] for k in range(0, 16, 4)]
        ip = "[" + ipaddress.IPv6Address(b"".join(words)).compressed + "]"
    return f"{ip}:{int(port, 16)}"


def wrench_samples(face_wrenches) -> np.ndarray:
    """``(n, 6, 6)`` face wrenches → ``(n, 36)`` ``pito-wrenches`` samples (face-major)."""
    W = np.asarray(face_wrenches, dtype=np.float32)
    if W.ndim != 3 or W.shape[1:] != (6, 6):
        raise ValueError(f"face_wrenches: expected shape (n, 6, 6), got {W.shape}")
    return W.reshape(W.shape[0], 36)


def contact_samples(contacts, n: int | None = None) -> np.ndarray:
    """A core-frame ``ContactEstimate`` with shapes ``(n, 6, …)`` → ``(n, 72)`` ``pito-contacts`` samples (face-major).

    ``contacts`` None (samples without their contacts): ``n`` rows of NaN with ``valid`` 0.
    """
    if contacts is None:
        out = np.full((int(n), 6, CONTACT_CHANNEL_COUNT // 6), np.nan, np.float32)
        out[:, :, 10] = 0.0  # valid
        return out.reshape(int(n), CONTACT_CHANNEL_COUNT)
    p = np.asarray(contacts.point, np.float32)
    if p.ndim != 3 or p.shape[1:] != (6, 3):
        raise ValueError(f"contacts.point: expected shape (n, 6, 3), got {p.shape}")
    return np.concatenate([p, np.asarray(contacts.normal, np.float32), np.asarray(contacts.force, np.float32),
                           np.asarray(contacts.torsion, np.float32)[..., None],
                           np.asarray(contacts.valid, np.float32)[..., None],
                           _single(contacts, p.shape[:2])[..., None]], axis=2).reshape(p.shape[0], CONTACT_CHANNEL_COUNT)


def _single(contacts, shape) -> np.ndarray:
    """``single`` channel ``(n, 6)``: 1/0 from ``single_contact``, NaN without the test."""
    s = getattr(contacts, "single_contact", None)
    if s is None:
        return np.full(shape, np.nan, np.float32)
    return np.asarray(s, np.float32).reshape(shape)


def _channels(desc, spec, prefix, frames):
    chans = desc.append_child("channels")
    for i in range(1, 7):
        for suffix, unit, kind in spec:
            ch = chans.append_child("channel")
            ch.append_child_value("label", f"{prefix}{i}_{suffix}")
            ch.append_child_value("unit", unit)
            ch.append_child_value("type", kind)
            ch.append_child_value("face", str(i))
            ch.append_child_value("frame", frames(i, kind))


def _common(desc, calibration: dict | None, assembly: dict | None, simulated: bool) -> None:
    acq = desc.append_child("acquisition")
    acq.append_child_value("manufacturer", "pito")
    acq.append_child_value("model", "PITO cube (6 faces x 6 gauges)")
    acq.append_child_value("simulated", "true" if simulated else "false")
    cal = desc.append_child("calibration")
    for key in ("method", "date", "hash", "source", "output_frame"):
        cal.append_child_value(key, "" if not calibration or calibration.get(key) is None else str(calibration[key]))
    asm = desc.append_child("assembly")
    asm.append_child_value("name", "" if not assembly else str(assembly.get("name")))
    if assembly:
        faces = asm.append_child("faces")
        for k, v in sorted(assembly.get("faces", {}).items()):
            faces.append_child_value(f"face{k}", str(v))
        asm.append_child_value("core_edge_m", repr(assembly.get("core_edge_m")))


def lsl_stream_infos(calibration: dict | None, assembly: dict | None, *, rate_hz: float = 1000.0,
                     source_id: str = "pito", simulated: bool = False):
    """``(wrench StreamInfo, contact StreamInfo)`` with the full ``desc`` (see the module docstring)."""
    import pylsl  # deferred: optional dependency (extra "interop"); pito_core.interop loads without it

    wi = pylsl.StreamInfo(WRENCH_STREAM, WRENCH_TYPE, 36, float(rate_hz), "float32", f"{source_id}-wrenches")
    d = wi.desc()
    _channels(d, WRENCH_CHANNELS, "F", lambda i, kind: f"pito_face_{i}")
    d.append_child_value("reference_frame", FACE_FRAME.format(i="i"))
    _common(d, calibration, assembly, simulated)
    ci = pylsl.StreamInfo(CONTACT_STREAM, CONTACT_TYPE, CONTACT_CHANNEL_COUNT, float(rate_hz), "float32",
                          f"{source_id}-contacts")
    d = ci.desc()
    _channels(d, CONTACT_CHANNELS, "C", lambda i, kind: "pito_core")
    d.append_child_value("reference_frame", CORE_FRAME)
    _common(d, calibration, assembly, simulated)
    return wi, ci


class LslPublisher:
    """A pipeline sink: pushes each :class:`~pito_core.pipeline.LiveBundle`'s samples to the two outlets.

    Samples go out as they arrive (``arrived_time``, ``arrived_face_wrenches``: each cube
    sample once, in order, not held back for the reference).

    Parameters
    ----------
    pipeline : Pipeline, PipelineProcess, PipelineThread or a live feed
        The pipeline producing the bundles: its calibration and assembly go into ``desc``,
        and it is asked to keep every sample's contacts (``set_sample_contacts(True)``): the
        ``pito-contacts`` samples are the bundles' ``arrived_contacts``, solved once, by the
        pipeline (a bundle made before that took effect gives NaN contacts, ``valid`` 0).
    rate_hz : float
        The cube's nominal rate, Hz.
    calibration_record, assembly_record : dict, optional
        Provenance for ``desc`` (default: built from the pipeline's).
    """

    def __init__(self, pipeline, *, rate_hz: float = 1000.0, source_id: str = "pito", simulated: bool = False,
                 calibration_record: dict | None = None, assembly_record: dict | None = None):
        import pylsl  # deferred: optional dependency (extra "interop"); pito_core.interop loads without it

        if pipeline.calibration is None:
            raise ValueError("calibration: the LSL streams carry wrenches; give a calibration (--calibration FILE)")
        self.pipeline = pipeline
        cal = calibration_record or _cal(pipeline.calibration)
        asm = assembly_record or _asm(pipeline.assembly if pipeline.assembly is not None else "cube")
        wi, ci = lsl_stream_infos(cal, asm, rate_hz=rate_hz, source_id=source_id, simulated=simulated)
        self.wrench_outlet = pylsl.StreamOutlet(wi, 0, 30)
        self.contact_outlet = pylsl.StreamOutlet(ci, 0, 30)
        self.clock_offset = pylsl.local_clock() - time.monotonic()
        self.pushed = 0
        self.names = (WRENCH_STREAM, CONTACT_STREAM)
        self.time_base = None  # (LSL time s, device tick µs) of the first sample published
        pipeline.set_sample_contacts(True)

    def __call__(self, bundle) -> None:
        # each cube sample once, as it arrives (its face wrenches do not wait for the reference);
        # a bundle of records only (their samples went out when they arrived) sends nothing
        W, t = bundle.arrived_face_wrenches, bundle.arrived_time
        if W is None or t is None or len(t) == 0 or len(W) != len(t):
            return
        tick = bundle.arrived_tick
        if tick is None or len(tick) != len(t):
            ts = (np.asarray(t, float) + self.clock_offset).tolist()
        else:
            if self.time_base is None:
                self.time_base = (float(t[0]) + self.clock_offset, int(tick[0]))
            ts = (self.time_base[0] + (np.asarray(tick, np.int64) - self.time_base[1]) * 1e-6).tolist()
        self.wrench_outlet.push_chunk(wrench_samples(W), ts)
        contacts = bundle.arrived_contacts
        if contacts is not None and len(contacts.valid) != len(ts):
            raise ValueError(f"arrived_contacts: expected {len(ts)} samples, got {len(contacts.valid)}")
        self.contact_outlet.push_chunk(contact_samples(contacts, len(ts)), ts)
        self.pushed += len(ts)

    def close(self) -> None:
        """Close both outlets (inlets see the streams end); the pipeline stops keeping every sample's contacts."""
        self.wrench_outlet = self.contact_outlet = None
        self.pipeline.set_sample_contacts(False)
