"""The live view: the patched object in 3D with contacts, side plots, tare/pause/record/replay; the feed that brings it the bundles."""

from .feed import LiveFeed
from .view import LiveView

__all__ = ["LiveFeed", "LiveView"]
