"""Element energies with analytic gradients and Hessians (numba), physics.md §2 and §1.6."""
