"""Element energies with analytic gradients and Hessians (numba), docs/physics.md §2 and §1.6."""
