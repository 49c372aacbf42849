"""The File menu's dialog actions: one way to add "File → <dialog>…" to the main window."""

from __future__ import annotations

__all__ = ["add_dialog_action"]


def add_dialog_action(window, label: str, make_dialog, name: str):
    """Add File → ``label`` to ``window``'s menu bar (creating the File menu if absent).

    The action opens ``make_dialog(window, recording_path)`` (the window's current recording or
    None), kept as ``window.<name>_dialog``; the action is ``window.<name>_action``.
    """
    bar = window.menuBar()
    menu = next((a.menu() for a in bar.actions() if a.menu() is not None and a.text().replace("&", "") == "File"), None)
    if menu is None:
        menu = bar.addMenu("&File")
    action = menu.addAction(label)

    def show():
        dlg = make_dialog(window, getattr(window, "recording_path", None))
        setattr(window, f"{name}_dialog", dlg)
        dlg.show()

    action.triggered.connect(show)
    setattr(window, f"{name}_action", action)
    return action
