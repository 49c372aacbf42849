"""Widgets of pito-app: coverage bars, time plots (each wraps a small model)."""
