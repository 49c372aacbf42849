"""The suite's grouping under ``make test`` (``-n 2 --dist loadgroup``, tests/conftest.py)."""

import pytest


def test_a_test_runs_in_its_group_under_loadgroup(request):
    """A file's tests share one worker (its module fixtures are built once) and every test that opens a
    window runs on one worker (they read the one X server's screen). pytest-xdist carries the group in
    the node id; pytest 9.2 dropped that, and a conftest marking groups after xdist read them left every
    test ungrouped (pytest-xdist#1386): nothing failed, the suite only got slower and racier."""
    if not getattr(request.config.option, "loadgroup", False):
        pytest.skip("not under pytest-xdist --dist loadgroup")
    assert request.node.nodeid.endswith("@tests/test_xdist_groups.py"), request.node.nodeid
