"""gearsim: nonlinear dynamics of a curve-face gear pair over two-parameter planes."""

from gearsim.numerics.cache import invalidate_stale_cache

__version__ = "0.1.0"

invalidate_stale_cache()
