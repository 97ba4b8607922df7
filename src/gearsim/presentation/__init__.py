"""Figures, report and explorer: they read results and never run the integrators."""
