"""Beyond one trajectory: coexisting attractors and basins, periodic orbits (shooting, Floquet
multipliers), continuation, bifurcation curves, landmarks."""
