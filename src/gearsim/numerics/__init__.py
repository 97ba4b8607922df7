"""Integrators on the one field: RK4 and DP5 steps, the event layer (contact switches), the period
loop, variational equations and the batched SIMD kernel."""
