"""Analysis: dead-volume simulation, fidelity, statistics."""
