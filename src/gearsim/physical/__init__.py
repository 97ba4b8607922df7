"""Gear geometry and units: the dimensional description and its conversion to the model's
dimensionless parameters."""
