"""The physics, once: the parameter set and the equations of motion (field and its tangent)."""
