"""gearsim: nonlinear dynamics of a curve-face gear pair over two-parameter planes."""

__version__ = "0.1.0"
