"""``pito reproduce``: re-run both papers' experiments on the simulator (placeholder)."""
