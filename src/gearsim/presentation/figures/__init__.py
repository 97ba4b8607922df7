"""The study's figures: one registry of figure builders, drawn from results."""
