"""Suite-wide: how pytest-xdist shares the tests between its workers (``make test`` runs ``-n 2``).

Every test that opens a window joins one group, ``display``, run by one worker in turn: the
pixel tests read the X server's screen, which all workers share. Every other test file is a
group of its own, so its module fixtures (a recording, a quick bench run) are built once.
"""

import pytest

_DISPLAY_FIXTURES = {"qtbot", "qapp", "styled"}


def pytest_itemcollected(item):
    """Each test's group, set as it is collected: pytest-xdist reads the groups in its own
    ``pytest_collection_modifyitems``, which runs before a conftest's."""
    shows = ("needs_display" in item.keywords or "gui" in item.keywords
             or not _DISPLAY_FIXTURES.isdisjoint(getattr(item, "fixturenames", ())))
    item.add_marker(pytest.mark.xdist_group("display" if shows else item.nodeid.split("::")[0]))
