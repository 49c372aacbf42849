"""Helpers for the device tests: drain a driver until a condition holds (with a safety timeout)."""

import time

import numpy as np
import pytest

from pito_core.devices import NetFTBatch, PitoBatch


def drain(device, until, timeout=60.0):
    """Read batches from ``device`` until ``until(batches)`` is true or ``timeout`` s passed."""
    batches = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        b = device.read(timeout=0.2)
        if b is not None:
            batches.append(b)
        if until(batches):
            break
    cls = PitoBatch if hasattr(device, "baudrate") else NetFTBatch
    return cls.concatenate(batches)


def n_rows(batches):
    return sum(len(b) for b in batches)


@pytest.fixture
def rng():
    return np.random.default_rng(0)
