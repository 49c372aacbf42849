"""LSL outlets, checked by inlets on the same machine — inside a PRIVATE network namespace only.

liblsl multicasts to discover peers. Every LSL process of these tests runs in a child
``unshare -n bash -c 'ip link set lo up; ...'`` (a network namespace with loopback only:
no packet can leave it) with ``LSLAPICFG`` pointing at the machine-only config. Where a
private namespace cannot be made (not root, no unshare/ip), the tests SKIP; they never fall
back to the normal namespace.
"""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pylsl", reason="the interop extra (pip install -e '.[interop]') is not installed")

from pito_core.interop import calibration_hash  # noqa: E402
from pito_core.interop import machine_only_config  # noqa: E402
from pito_core.pipeline import replay_recording  # noqa: E402

from .conftest import ASSEMBLY, ideal_calibration  # noqa: E402

CHILD = Path(__file__).with_name("_lsl_child.py")


def _namespace_problem() -> str | None:
    if not (shutil.which("unshare") and shutil.which("ip")):
        return "unshare or ip (iproute2) not installed: cannot make a private network namespace for LSL"
    r = subprocess.run(["unshare", "-n", "bash", "-c", "ip link set lo up && ip -o link | wc -l"],
                       capture_output=True, text=True, timeout=30)
    if r.returncode != 0:
        return f"cannot make a private network namespace (unshare -n needs root/CAP_SYS_ADMIN): {r.stderr.strip()}"
    if r.stdout.strip() != "1":
        return f"the private namespace has {r.stdout.strip()} links, expected loopback only"
    return None


@pytest.fixture(scope="module")
def namespace(tmp_path_factory):
    problem = _namespace_problem()
    if problem:
        pytest.skip(f"LSL tests need a private network namespace: {problem}")
    return machine_only_config(tmp_path_factory.mktemp("lsl") / "lsl_api.cfg")


def in_namespace(cfg, script: str, timeout=180) -> dict:
    """Run ``script`` (bash) in a new private network namespace with LSLAPICFG=cfg; the RESULT JSON line."""
    env = dict(os.environ, LSLAPICFG=str(cfg), PYTHONPATH=str(Path(__file__).parents[2]))
    r = subprocess.run(["unshare", "-n", "bash", "-c", f"set -e; ip link set lo up; {script}"], env=env,
                       capture_output=True, text=True, timeout=timeout)
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("RESULT ")]
    assert r.returncode == 0 and lines, f"rc={r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}"
    return json.loads(lines[-1][len("RESULT "):])


def test_machine_only_config_keeps_discovery_on_loopback(namespace):
    text = Path(namespace).read_text()
    assert "ResolveScope = machine" in text and "IPv6 = disable" in text and "KnownPeers = {127.0.0.1}" in text
    for key in ("LinkAddresses", "SiteAddresses", "OrganizationAddresses", "GlobalAddresses"):
        assert f"{key} = {{}}" in text


def test_recording_through_the_outlets_arrives_exactly(namespace, interop_files):
    _, cal, rec, _ = interop_files
    out = in_namespace(namespace, f"{sys.executable} {CHILD} {rec} {cal} {ASSEMBLY}")
    w, c = out["infos"]["pito-wrenches"], out["infos"]["pito-contacts"]
    assert (w["type"], w["channel_count"], w["rate"]) == ("Force", 36, 1000.0)
    assert (c["type"], c["channel_count"]) == ("Contact", 72)
    assert [ch["label"] for ch in w["channels"][:7]] == ["F1_fx", "F1_fy", "F1_fz", "F1_tx", "F1_ty", "F1_tz", "F2_fx"]
    assert [ch["unit"] for ch in w["channels"][:6]] == ["N", "N", "N", "N*m", "N*m", "N*m"]
    assert {ch["face"] for ch in w["channels"]} == {str(i) for i in range(1, 7)}
    assert [ch["label"] for ch in c["channels"][:13]] == ["C1_px", "C1_py", "C1_pz", "C1_nx", "C1_ny", "C1_nz",
                                                          "C1_fx", "C1_fy", "C1_fz", "C1_torsion", "C1_valid",
                                                          "C1_single", "C2_px"]
    assert c["channels"][0]["unit"] == "m" and c["channels"][9]["unit"] == "N*m"
    for info in (w, c):
        assert info["calibration"]["hash"] == calibration_hash(ideal_calibration())
        assert info["calibration"]["method"] == "ideal" and info["calibration"]["date"].startswith("2026-11-23")
        assert info["assembly"] == ASSEMBLY and info["face1"]
    bundle, _ = replay_recording(rec, ideal_calibration(), ASSEMBLY)
    assert out["sent"] == len(bundle.time) > 0  # every sample of the recording, through the same pipeline
    assert out["received"] == {"pito-wrenches": out["sent"], "pito-contacts": out["sent"]}
    assert out["wrench_max_abs_diff"] == 0.0  # float32 on the wire, compared as float32
    assert out["contact_max_abs_diff"] == 0.0 and out["contact_nan_same"]
    assert out["contacts_from_bundles"]  # the publisher solves nothing: the pipeline's per-sample contacts
    assert out["timestamps_max_abs_diff"] < 1e-9  # the cube's device clock on the LSL clock, not push times
    assert out["timestamps_strictly_increasing"] and out["valid_contacts"] > 0


def test_pito_stream_from_simulated_devices(namespace, interop_files):
    _, cal, _, _ = interop_files
    pito = f"{sys.executable} -c 'import sys; from pito_core.cli import main; sys.exit(main())'"
    out = in_namespace(namespace, f"{pito} stream --pito sim --ati sim --calibration {cal} --object {ASSEMBLY} "
                                  f"--duration 8 & {sys.executable} {CHILD} receive 3; wait")
    for name, kind, n_ch in (("pito-wrenches", "Force", 36), ("pito-contacts", "Contact", 72)):
        s = out[name]
        assert (s["type"], s["channel_count"]) == (kind, n_ch)
        assert s["n"] > 0 and s["monotonic"] and s["simulated"] == "true"
        assert s["calibration_hash"] == calibration_hash(ideal_calibration())
        assert np.isfinite(s["lag_s"]) and abs(s["lag_s"]) < 60  # stamps are on the LSL clock (not device µs)
    assert out["pito-wrenches"]["finite_fraction"] == 1.0


def test_pito_record_lsl_publishes_and_embeds_provenance(namespace, interop_files, tmp_path):
    from pito_core.io import read_recording

    _, cal, _, _ = interop_files
    rec = tmp_path / "lsl.pitorec"
    pito = f"{sys.executable} -c 'import sys; from pito_core.cli import main; sys.exit(main())'"
    out = in_namespace(namespace, f"{pito} record --pito sim --ati sim --calibration {cal} --object {ASSEMBLY} --lsl "
                                  f"--duration 8 --progress 0 -o {rec} & {sys.executable} {CHILD} receive 3; wait")
    s = out["pito-wrenches"]
    assert s["channel_count"] == 36 and s["n"] > 0 and s["monotonic"]
    assert s["calibration_hash"] == calibration_hash(ideal_calibration())
    meta = read_recording(rec).meta
    assert meta["calibration"]["hash"] == s["calibration_hash"] and meta["assembly"]["name"] == ASSEMBLY
