"""The live view: the patched object in 3D with contacts, side plots, tare/pause/record/replay."""

from .view import LiveView

__all__ = ["LiveView"]
